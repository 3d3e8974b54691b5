"""Files in: readers of measured records and FRFs per format, record quality, and importers of
finite-element models (OpenSeesPy scripts, exported matrices)."""
