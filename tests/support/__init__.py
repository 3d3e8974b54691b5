"""Helpers shared by the tests (tests/conftest.py puts tests/ on sys.path, so a test
writes ``from support.frames import shear_K``). Fixtures stay in tests/conftest.py.

frames: shear-frame matrices, the paper's Table 1 values, random systems;
cases: small case folders (YAML + NPZ) from the four-story truth;
cli: the command line in a subprocess or in-process, and folder snapshots;
diagnosis: small frames with FRF files for the diagnosis tests.
"""
