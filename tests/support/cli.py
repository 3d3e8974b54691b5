"""The command line as a user runs it (subprocess) or in this process, and snapshots of
the files a run may touch."""

import contextlib
import hashlib
import io
import os
import subprocess
import sys
import types

from nlp.cli import main
from support.paths import ROOT


def cli(*args, env=None, **kw):
    """The real command in a subprocess (exit status, stderr, no traceback as a user sees)."""
    e = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    e.update(env or {})
    return subprocess.run([sys.executable, "-m", "nlp", *map(str, args)], capture_output=True,
                          text=True, env=e, timeout=240, **kw)


def cli_inproc(*args):
    """The same entry point in this process (saves a CasADi import per input mistake); an
    exception escaping main() would be the traceback a user sees, and fails the test."""
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        rc = main([str(a) for a in args])
    return types.SimpleNamespace(returncode=rc, stdout=out.getvalue(), stderr=err.getvalue())


def snapshot(folder):
    """Every file under folder (and the siblings a run could leave) -> sha256."""
    out = {}
    parent = os.path.dirname(folder)
    for name in sorted(os.listdir(parent)):
        p = os.path.join(parent, name)
        if not name.startswith(os.path.basename(folder)):
            continue
        if os.path.isfile(p):
            out[name] = hashlib.sha256(open(p, "rb").read()).hexdigest()
        for root, _, files in os.walk(p):
            for f in files:
                q = os.path.join(root, f)
                out[os.path.relpath(q, parent)] = hashlib.sha256(open(q, "rb").read()).hexdigest()
    return out
