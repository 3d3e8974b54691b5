"""Decision pieces of :mod:`nlp.diagnose`, one concept per module.

* :mod:`.evidence` - quasi-likelihood evidence, significance, ties, agreement between tests;
* :mod:`.priors` - fitted parameters against their stated prior, damping decomposition;
* :mod:`.band` - whole-band residual map and unexplained resonances (extra modes).
"""
