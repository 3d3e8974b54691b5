"""Docs that cannot drift: the case-file reference is generated from nlp/case/schema.py and covers
every key the loader accepts; every public function and class of every module has the
docstring the API pages (pdoc) render."""

import importlib
import inspect
import os
import pkgutil
import re
from pathlib import Path

import pytest

import nlp
from nlp.case import reference as case_reference

ROOT = Path(__file__).resolve().parents[2]


def test_committed_case_reference_is_current():
    committed = (ROOT / "docs" / "case_reference.md").read_text()
    assert committed == case_reference.reference(), "run: python -m nlp.case.reference"


def test_every_key_the_loader_accepts_is_documented():
    """The key sets of the loader's check_keys calls, section by section."""
    src = "".join((ROOT / "nlp" / "case" / name).read_text() for name in ("load.py", "load_data.py"))
    ref = case_reference.reference()
    sections = dict(case_reference.SECTIONS)
    found = 0
    for section, keys in re.findall(r'check_keys\(\w+, "([\w.]+)", \{([^}]*)\}', src):
        if section not in sections:
            continue
        block = ref.split(f"## `{section}`")[1].split("\n## ")[0]
        for key in re.findall(r'"(\w+)"', keys):
            found += 1
            nested = f"## `{section}.{key}`" in ref  # a subsection (data.screen)
            assert f"| `{key}` |" in block or nested, f"{section}.{key} is not documented"
    assert found > 40


def _modules():
    return [m.name for m in pkgutil.walk_packages(nlp.__path__, "nlp.") if m.name != "nlp.__main__"]


@pytest.mark.parametrize("name", _modules())
def test_public_functions_have_docstrings(name):
    mod = importlib.import_module(name)
    assert (mod.__doc__ or "").strip(), f"{name} has no module docstring"
    names = getattr(mod, "__all__", None) or [
        n for n, o in vars(mod).items() if not n.startswith("_")
        and (inspect.isfunction(o) or inspect.isclass(o)) and o.__module__ == name]
    for n in names:
        obj = getattr(mod, n)
        if inspect.isfunction(obj) or inspect.isclass(obj):
            assert (obj.__doc__ or "").strip(), f"{name}.{n} has no docstring"


def test_api_docs_build(tmp_path):
    pdoc = pytest.importorskip("pdoc")
    from pdoc import pdoc as build, render

    render.configure(docformat="numpy")
    build("nlp.io.readers", "nlp.frf.estimate", "nlp.io.quality", output_directory=tmp_path)
    page = (tmp_path / "nlp" / "frf" / "estimate.html").read_text()
    assert "hv_tls" in page and "total-least-squares" in page
    assert pdoc.__version__ and os.path.isfile(tmp_path / "nlp" / "io" / "quality.html")


def test_cli_version_and_help_give_defaults_and_exit_codes(capsys):
    from nlp.cli import main

    with pytest.raises(SystemExit) as ex:
        main(["--version"])
    assert ex.value.code == 0 and capsys.readouterr().out.strip() == f"frf-nlp {nlp.__version__}"
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = capsys.readouterr().out
    assert "else 20" in text and "exit status" in text and "130" in text and "  3 " in text
