"""Independent simulators and case writers for the tests and the benchmarks.

The modules here make the data that the package is checked against, so those used as
independent truth share no code with the package's FRF and time-stepping code
(`nlp.frf`, `nlp.model`): `frames`, `noise_sim`, `sparse_sim`, `monitoring` and `blind`
solve the dynamic stiffness and integrate the equations of motion themselves. `four_story`,
`shake_table` and `benchmark` build their truth with the package's damping, FRF and
simulation functions; they make data for tests that check fitting and diagnosis, not
those functions.

Modules: `frames` (shear-frame stiffness), `noise_sim` (null cases of small frames on
every FRF route), `sparse_sim` (FRFs of large models by sparse solves), `monitoring`
(FRF records of a frame over weeks), `four_story` (the paper's four-story frame),
`shake_table` (its shake-table test), `benchmark` (the concealed-effect benchmark),
`blind` (the blind benchmark).
"""
