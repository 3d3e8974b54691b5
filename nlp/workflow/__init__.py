"""One run of a case: its updates, their average, the re-centred reduced basis and the
time-domain verification."""
