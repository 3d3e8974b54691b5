"""Compile CasADi functions to C once and cache the shared library.

Small per-frequency functions compile in about a second with gcc; one big
expanded graph over all frequencies does not (it exhausted gcc in our tests),
so the builder compiles only per-frequency pieces and maps them. Libraries are
cached by a hash of the generated source, so the same problem structure is
compiled once per machine. Without a working C compiler the caller falls back
to CasADi's SX virtual machine (same results, slower).
"""

import hashlib
import os
import shutil
import subprocess
import tempfile
import warnings

import casadi as ca

from nlp.output.progress import stage
from nlp.output.provenance import sha256_file as _sha256

__all__ = ["cache_dir", "compile_library"]

_FLAGS = ["-fPIC", "-shared"]


def cache_dir():
    """``$FRF_NLP_CACHE``, else ``$XDG_CACHE_HOME/frf-nlp``, else ``~/.cache/frf-nlp``."""
    root = os.environ.get("FRF_NLP_CACHE")
    if not root:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        root = os.path.join(base, "frf-nlp")
    return root


def compile_library(functions, stem="frfnlp", optimize=True):
    """Generate C for ``functions``, compile and return the .so path, or None.

    optimize=False builds at -O0 instead of -O2: about 2-3x faster to compile and
    about 2x slower to run, with bit-identical results (no fast-math, so gcc keeps
    IEEE semantics at every level). It pays for problems solved only a few times,
    where gcc's time dominates (a diagnose refit: 3-5 solves). The level is part
    of the cache key.

    Returns None (with a warning) when no compiler is available or the build
    fails; the caller then evaluates the SX functions directly.
    """
    compiler = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    if compiler is None:
        warnings.warn("no C compiler found; CasADi functions run uncompiled (slower)")
        return None
    cg = ca.CodeGenerator(f"{stem}.c", {"with_header": False})
    for f in functions:
        cg.add(f)
    src = cg.dump()
    flags = ["-O2" if optimize else "-O0", *_FLAGS]
    key = hashlib.sha1((src + " ".join(flags) + ca.__version__).encode()).hexdigest()[:16]
    root = cache_dir()
    lib = os.path.join(root, f"{stem}_{key}.so")
    probe = functions[0].name()
    if os.path.exists(lib):
        if _intact(lib, probe):
            return lib
        # a truncated, garbage or foreign file in the cache is our problem, not the user's
        warnings.warn(f"cached library {lib} is damaged (size or sha256 does not match, or it "
                      "does not load); rebuilding it")
    try:
        os.makedirs(root, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=root) as tmp:
            c_file = os.path.join(tmp, f"{stem}.c")
            with open(c_file, "w") as fh:
                fh.write(src)
            tmp_lib = os.path.join(tmp, "lib.so")
            with stage("compile C", unit="library") as bar:
                subprocess.run([compiler, *flags, c_file, "-o", tmp_lib, "-lm"],
                               check=True, capture_output=True, timeout=600)
                bar.update()
            if not _loads(tmp_lib, probe):
                raise OSError("the freshly compiled library does not load")
            tmp_sum = os.path.join(tmp, "lib.sha256")
            _write_sum(tmp_lib, tmp_sum)
            # atomic renames: concurrent builders never see a partial file; the .so goes
            # last so that a reader who finds it also finds its checksum
            os.replace(tmp_sum, lib + ".sha256")
            os.replace(tmp_lib, lib)
    except (OSError, subprocess.SubprocessError) as exc:
        warnings.warn(f"compiling CasADi functions failed ({exc}); running uncompiled")
        return None
    return lib


def _loads(lib, name):
    """True if CasADi can load function ``name`` from the shared library."""
    try:
        ca.external(name, lib)
    except RuntimeError:
        return False
    return True


def _intact(lib, name):
    """The cached library matches its recorded sha256 and size, and loads."""
    try:
        with open(lib + ".sha256") as fh:
            digest, size = fh.read().split()
    except FileNotFoundError:  # cached before checksums existed: adopt it if it loads
        if not _loads(lib, name):
            return False
        try:
            _write_sum(lib, lib + ".sha256")
        except OSError:
            pass
        return True
    except (OSError, ValueError):
        return False
    if os.path.getsize(lib) != int(size) or _sha256(lib) != digest:
        return False
    return _loads(lib, name)


def _write_sum(lib, path):
    """Record sha256 and size of ``lib`` in ``path`` (atomically)."""
    tmp = f"{path}.{os.getpid()}.tmp"
    with open(tmp, "w") as fh:
        fh.write(f"{_sha256(lib)} {os.path.getsize(lib)}\n")
    os.replace(tmp, path)
