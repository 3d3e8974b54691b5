"""Monitoring: the same model updated from every record of a campaign, change detection in the
parameter history, and its trend report."""
