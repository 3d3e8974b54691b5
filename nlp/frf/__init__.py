"""Frequency response functions: output forms, the numpy reference FRF, estimation from records
(H1/H2/Hv), the noise of a measured FRF, frequency-point selection, peak picking, metrics
(FDAC/FRAC/MAC), time simulation, and the FRF backends the NLP evaluates (:mod:`.backends`)."""
