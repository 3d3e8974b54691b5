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

__all__ = ["cache_dir", "compile_library"]

_FLAGS = ["-O2", "-fPIC", "-shared"]


def cache_dir():
    """``$FRF_NLP_CACHE``, else ``$XDG_CACHE_HOME/frf-nlp``, else ``~/.cache/frf-nlp``."""
    root = os.environ.get("FRF_NLP_CACHE")
    if not root:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        root = os.path.join(base, "frf-nlp")
    return root


def compile_library(functions, stem="frfnlp"):
    """Generate C for ``functions``, compile and return the .so path, or None.

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
    key = hashlib.sha1((src + " ".join(_FLAGS) + ca.__version__).encode()).hexdigest()[:16]
    root = cache_dir()
    lib = os.path.join(root, f"{stem}_{key}.so")
    if os.path.exists(lib):
        return lib
    try:
        os.makedirs(root, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=root) as tmp:
            c_file = os.path.join(tmp, f"{stem}.c")
            with open(c_file, "w") as fh:
                fh.write(src)
            tmp_lib = os.path.join(tmp, "lib.so")
            subprocess.run([compiler, *_FLAGS, c_file, "-o", tmp_lib, "-lm"],
                           check=True, capture_output=True, timeout=600)
            os.replace(tmp_lib, lib)  # atomic: concurrent builders never see a partial file
    except (OSError, subprocess.SubprocessError) as exc:
        warnings.warn(f"compiling CasADi functions failed ({exc}); running uncompiled")
        return None
    return lib
