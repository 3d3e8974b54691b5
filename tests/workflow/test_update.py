"""From records to a verified model: H1, two updates averaged, replay, report."""

import json
import os
import re
import shutil

import numpy as np
import pytest

from nlp.testing.shake_table import make
from nlp.cli import main
from support.paths import CASES

CASE = os.path.join(CASES, "four_story_shake_table", "case.yaml")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("shake")
    t, cols, truth = make(seed=5)
    names = list(cols)
    np.savetxt(d / "records.csv", np.column_stack([cols[n] for n in names]), delimiter=",",
               header=",".join(names), comments="")
    shutil.copy(CASE, d / "case.yaml")
    out = d / "out"
    assert main(["run", str(d / "case.yaml"), "--out", str(out), "--starts", "2",
                 "--workers", "1"]) == 0
    return out, truth


def test_table1_average_and_accuracy(run_dir):
    out, truth = run_dir
    rows = [ln.split(",") for ln in (out / "table1.csv").read_text().strip().splitlines()]
    assert [r[0] for r in rows] == ["Parameter (kg or N/m)", "Initial", "Updated (accelerance)",
                                    "Updated (receptance)", "Average of the updated"]
    head = rows[0]
    acc, rec, avg = (np.array(r[1:], float) for r in rows[2:])
    np.testing.assert_allclose(avg, 0.5 * (acc + rec), rtol=1e-5)
    for i, k in enumerate(truth["stiffnesses"]):
        assert abs(avg[head.index(f"k{i + 1}") - 1] / k - 1) < 0.03


def test_fdac_and_time_domain(run_dir):
    out, _ = run_dir
    s = json.loads((out / "summary.json").read_text())
    assert min(s["fdac"].values()) >= 0.98
    assert s["time_domain"]["a4"]["nrmse"] <= 0.10
    assert s["time_domain"]["d4"]["correlation"] > 0.99
    assert (out / "time_a4.png").stat().st_size > 10_000


def test_report_rebuilds_and_links_existing_figures(run_dir):
    out, _ = run_dir
    first = (out / "report.html").read_text()
    os.remove(out / "report.html")
    assert main(["report", str(out)]) == 0
    html = (out / "report.html").read_text()
    assert html == first and "Table 1" in html and "Time-domain" in html
    imgs = re.findall(r'<img src="([^"]+)"', html)
    assert len(imgs) >= 8 and all((out / p).is_file() for p in imgs)


def test_report_on_a_non_run_folder_is_a_clear_error(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 2
    assert "summary.json" in capsys.readouterr().err


def test_report_shows_percent_units_c_and_provenance(run_dir):
    out, _ = run_dir
    page = (out / "report.html").read_text()
    summary = json.loads((out / "summary.json").read_text())
    nrmse = summary["time_domain"]["a1"]["nrmse"]
    assert f"{100 * nrmse:.1f} %" in page                       # percent, as the console
    assert "C of the final model [N s/m]" in page and "Provenance" in page
    assert "absolute acceleration per ground acceleration" in page
    assert "relative displacement per ground acceleration" in page and "s^2" in page
    C = np.asarray(summary["model"]["C"])
    assert f"{C[0, 0]:.6g}" in page
