"""The README's Python example runs as written, and what it prints is the run's result."""

import contextlib
import io
import json
import os
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_readme_python_example_runs(tmp_path, monkeypatch):
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert blocks, "README.md has no ```python block"
    (tmp_path / "cases").symlink_to(ROOT / "cases")
    monkeypatch.chdir(tmp_path)
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(blocks[0], "README.md", "exec"), {})
    # the example prints the objective and k1 as the files it wrote hold them
    out = [p for p in (tmp_path / "results").iterdir()]
    assert len(out) == 1
    doc = json.loads((out[0] / "result.json").read_text())
    k1 = next(p for p in doc["parameters"] if p["name"] == "k1")
    last = printed.getvalue().strip().splitlines()[-1].split()
    assert float(last[0]) == doc["objective"]["updated"]
    assert float(last[1]) == k1["updated"]
    assert os.path.isfile(out[0] / "report.html")
    # and the answer is physics: story 1 within 4 standard errors (and 3 %) of the truth
    truth = json.loads((ROOT / "cases" / "four_story_shear_frame" / "truth.json").read_text())
    k1_true = truth["stiffnesses"][0]
    assert abs(k1["updated"] - k1_true) < 4 * k1["standard_error"]
    assert abs(k1["updated"] / k1_true - 1) < 0.03
