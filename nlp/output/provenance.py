"""Provenance of a result: which code, when, how it was called, on which files.

``provenance(cfg)`` is the top-level ``"provenance"`` key of result.json,
summary.json and diagnosis.json (report.html shows it): package version, git
commit when the package runs from a checkout (with ``dirty`` when it has
uncommitted changes), the date in UTC (ISO 8601), the command line, and the
sha256 of the case file and of every data or model file it names.
"""

from datetime import datetime, timezone
import hashlib
import os
import shlex
import subprocess
import sys

import nlp
from nlp import __version__

__all__ = ["provenance", "package_version", "git_commit", "sha256_file", "case_files"]


def package_version():
    """The installed frf-nlp version (``0+unknown`` for a source tree not installed)."""
    return __version__


def git_commit():
    """{"commit", "dirty"} of the checkout holding the package, or None."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(nlp.__file__)))
    if not os.path.exists(os.path.join(root, ".git")):
        return None
    try:
        head = subprocess.run(["git", "-C", root, "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=10)
        if head.returncode != 0:
            return None
        st = subprocess.run(["git", "-C", root, "status", "--porcelain", "--untracked-files=no",
                             "--", "nlp"], capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return {"commit": head.stdout.strip(), "dirty": bool(st.stdout.strip())}


def sha256_file(path):
    """Hex sha256 of a file's bytes, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def case_files(cfg):
    """The case file and every file it reads (data, model, held-out test, other levels)."""
    files = [cfg.path, cfg.data.file, cfg.model.file, cfg.data.validation_file,
             *cfg.data.level_files]
    return list(dict.fromkeys(f for f in files if f))


def provenance(cfg, argv=None):
    """The provenance record of a run on case ``cfg`` (see the module docstring)."""
    argv = list(sys.argv if argv is None else argv)
    if argv and os.path.basename(argv[0]) in ("__main__.py", "frf-nlp"):
        argv[0] = "frf-nlp"  # python -m nlp and the console script are the same command
    return {
        "package": "frf-nlp",
        "version": package_version(),
        "git": git_commit(),
        "date_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "command_line": " ".join(shlex.quote(a) for a in argv),
        "python": sys.version.split()[0],
        "files": {f: {"sha256": sha256_file(f), "bytes": os.path.getsize(f)}
                  for f in case_files(cfg)},
    }
