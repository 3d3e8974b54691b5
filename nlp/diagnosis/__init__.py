"""Missing physics: :func:`nlp.diagnosis.driver.diagnose` and its stages, one concept per module.

* :mod:`.driver` - the pipeline: screen, points and baseline, levels, selection, widen,
  checks, verdict (stage data in :mod:`.look`);
* :mod:`.fitting` - the updating problem on the fitted points, its residuals and windows;
* :mod:`.candidates` - candidate families x locations and their score test;
* :mod:`.refit` - candidate refits, re-solves of the current model, backward elimination;
* :mod:`.decide` - evidence of one round of refits, acceptance, adequacy of a model;
* :mod:`.others` - the case's other tests of the same structure;
* :mod:`.widen` - when a look widens its windows, and the windows it fits;
* :mod:`.checks` - phase, loss and whole-band checks of the final model;
* :mod:`.verdict` - the verdict, its statements and diagnosis.json;
* :mod:`.screen` - set-up screening before any fit;
* :mod:`.families` - the candidate physics as model enrichments;
* :mod:`.inside` - effects inside the model class (priors, damping decomposition);
* :mod:`.levels` - level dependence (nonlinearity) from tests at two excitation levels;
* :mod:`.evidence` - quasi-likelihood evidence, significance, ties, agreement between tests;
* :mod:`.priors` - fitted parameters against their stated prior, damping decomposition;
* :mod:`.band` - whole-band residual map and unexplained resonances (extra modes);
* :mod:`.harmonics` - where a nonlinearity acts, from the response outside the excitation band;
* :mod:`.loss` - hysteretic loss from magnitude and phase together;
* :mod:`.phase` - sensor time delays from the phase of the FRFs;
* :mod:`.resolution` - whether the data resolve an appendage from a reshaped peak;
* :mod:`.spread` - how far a right noise model's reduced chi-square strays from 1 on the
  fitted points (errors shared between channels and neighbouring bins);
* :mod:`.plots` - the diagnosis figures.
"""
