"""The blind benchmark for `frf-nlp diagnose`: tests the package was not built on.

Independent of the package: nothing here imports `nlp` outside `nlp.testing`. Structures,
signals, simulation, sensors and the FRF files are all written here:

* 3- to 5-storey shear frames with non-proportional viscous damping (Rayleigh
  plus random story dashpots), ordinary deviations of the real structure from
  its design values (stiffness up to 10 %, mass up to 5 %; "ordinary" cases up
  to 30 % in stiffness and 10 % in mass) (`structures`);
* shake-table tests (table acceleration) and shaker tests (force at a random
  floor); a chirp in ONE segment that starts and ends at rest, or a long random
  record for Welch averaging (`experiment`);
* simulation at 20x the recorders' rate: a Newmark average-acceleration
  integrator written here (linear systems), scipy `solve_ivp` (RK45, nonlinear
  story springs: cubic or a contact gap), or exact frequency-domain filtering
  (hysteretic damping, which has no causal time-domain form) (`simulators`); then an
  8th-order Butterworth anti-alias filter on every channel and decimation;
* sensors: the input (table accelerometer or force cell), a base accelerometer
  on the table (shake-table tests), floor accelerometers [g] and LVDTs [mm]
  relative to the table; 1.5-2 % white noise on every channel, the input too;
* effects of every family of the tool at sizes from barely detectable to
  large, cases with two effects at once, null cases and ordinary-change cases;
* a few FRF-file cases (H1 estimated here by Welch averaging, with and without
  the coherence), so that every FRF route of the tool is scored (`cases`).

Each case folder has the records (or frf.npz), case.yaml written by ONE recipe
from the test description only (`recipe.case_yaml`: the design model, the excitation
band as the frequency range, the sensors), and truth.json, which only
scripts/score_blind.py reads. scripts/make_blind_benchmark.py writes the cases.
"""
