"""Where the repository, its committed cases and its scripts are (tests/data/README.md lists
what the tests read from them), and how a test loads a script as a module."""

import importlib.util
import os
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))  # the repository
CASES = os.path.join(ROOT, "cases")
SCRIPTS = os.path.join(ROOT, "scripts")


def load_script(name, needs=()):
    """scripts/NAME.py as a module; the scripts it imports by name (needs) are loaded the
    same way first. Each is registered in sys.modules, so nothing edits sys.path."""
    for dep in needs:
        load_script(dep)
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, os.path.join(SCRIPTS, f"{name}.py"))
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
    return sys.modules[name]
