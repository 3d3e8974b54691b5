"""Decision pieces of :mod:`nlp.diagnosis.driver`, one concept per module.

* :mod:`.evidence` - quasi-likelihood evidence, significance, ties, agreement between tests;
* :mod:`.priors` - fitted parameters against their stated prior, damping decomposition;
* :mod:`.band` - whole-band residual map and unexplained resonances (extra modes);
* :mod:`.harmonics` - where a nonlinearity acts, from the response outside the excitation band;
* :mod:`.loss` - hysteretic loss from magnitude and phase together;
* :mod:`.phase` - sensor time delays from the phase of the FRFs;
* :mod:`.resolution` - whether the data resolve an appendage from a reshaped peak;
* :mod:`.spread` - how far a right noise model's reduced chi-square strays from 1 on the
  fitted points (errors shared between channels and neighbouring bins).
"""
