"""The lab benchmark: the blind benchmark's cases in a lab that is not ideal (issue 48).

Independent of the package: nothing here imports `nlp` outside `nlp.testing`. On top of the
blind benchmark's structures, signals, simulators and recipe (imported from
`nlp.testing.blind`), every case carries

* a calibration error on every channel, the input too, and each channel's own anti-alias
  low-pass and delay, input and response chains differing (`chain`);
* coloured (white + 1/f) and partly common-mode noise of fixed absolute level (`noise`);
* a shake table that does not reproduce the drive (a platen on a servo actuator, loaded by
  the structure's base reaction) or a shaker whose armature loads the floor (`table`);
* slightly nonlinear joints in every shear frame (`links`, simulated by `effects`);

and the case list adds frames that are not shear buildings (flexible beams, `frames`,
`structures`), planar models of eccentric 3-D frames (torsion), and effects outside the
tool's families: Coulomb friction, a breathing crack, a sliding mass (`links`).
docs/benchmarks/lab_generator.md states each imperfection's size and why;
scripts/make_lab_benchmark.py writes the cases, scripts/score_lab.py scores them.
"""
