"""Progress on stderr (nlp.output.progress): shown on a terminal, and off a terminal the
commands print exactly what they printed before it existed."""

import fcntl
import io
import os
import pty
import re
import struct
import subprocess
import sys
import termios
from pathlib import Path

import pytest

from nlp.output import progress
from support.diagnosis import coupled_case

ROOT = Path(__file__).resolve().parents[2]
CASE = ROOT / "cases" / "four_story_shear_frame" / "case.yaml"
RUN = ["run", str(CASE), "--starts", "4", "--seed", "0"]
BAR = re.compile(r"[\r\x1b]|[\u2580-\u259f]|\d+/\d+ \[")   # \r, escapes, block glyphs, n/N [


def _env(code_root):
    env = dict(os.environ, PYTHONPATH=str(code_root))
    env.pop("COLUMNS", None)
    return env


def _under_pty(args, out, timeout=120):
    """(stdout, stderr) of ``python -m nlp args --out out`` with stderr a 30 x 120 terminal."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 120, 0, 0))
    proc = subprocess.Popen([sys.executable, "-m", "nlp", *args, "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=slave, env=_env(ROOT), cwd=ROOT)
    os.close(slave)
    err = b""
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:   # EIO: the child closed the terminal
            break
        if not chunk:
            break
        err += chunk
    os.close(master)
    stdout = proc.stdout.read().decode()
    assert proc.wait(timeout=timeout) == 0
    return stdout, err.decode(errors="replace")


def _piped(code_root, args, out, timeout=120):
    proc = subprocess.run([sys.executable, "-m", "nlp", *args, "--out", str(out)],
                          capture_output=True, env=_env(code_root), cwd=ROOT, timeout=timeout)
    assert proc.returncode == 0, proc.stderr.decode()
    return proc.stdout.decode(), proc.stderr.decode()


def _comparable(text, out):
    """The output with the --out folder named OUT and timings (they vary run to run) as T."""
    return re.sub(r"\d+\.\d+ s\b", "T s", text.replace(str(out), "OUT"))


def test_run_on_a_terminal_shows_stages_counts_and_each_start(tmp_path):
    stdout, err = _under_pty(RUN, tmp_path / "out")
    for name in ("build NLP", "local solves", "polishing"):
        assert name in err
    assert "1/1 [" in err and "4/4 [" in err           # n/N of build, starts, polishing
    assert re.search(r"\[\d\d:\d\d<\d\d:\d\d", err)    # elapsed < remaining
    starts = re.findall(r"start (\d): (\d+) iterations, f = ([0-9.e+-]+), [0-9.]+ s", err)
    assert {s[0] for s in starts} >= {"0", "1", "2", "3"}
    assert all(int(s[1]) > 0 and float(s[2]) < 1 for s in starts)
    assert not BAR.search(stdout)                      # stdout is a pipe: no bar there
    assert "search: 4/4 local solves" in stdout


def test_batch_on_a_terminal_counts_the_records(tmp_path):
    records = sorted(str(p) for p in (ROOT / "cases" / "monitoring" / "records").glob("*.npz"))
    stdout, err = _under_pty(["batch", str(ROOT / "cases" / "monitoring" / "case.yaml"),
                              *records[:3], "--starts", "2"], tmp_path / "out")
    assert "records" in err and "3/3 [" in err and "local solves" not in err
    assert "  [3/3] " in stdout                        # the log lines, as piped before
    assert not re.search(r"[\r\x1b\u2580-\u259f]", stdout)


def test_run_piped_prints_only_its_log_lines(tmp_path):
    """Off a terminal nothing of the progress is written: stderr stays empty, as it was before
    progress existed, and stdout holds the same lines as under a terminal."""
    stdout, stderr = _piped(ROOT, RUN, tmp_path / "piped")
    assert stderr == ""
    on_tty, _ = _under_pty(RUN, tmp_path / "tty")
    assert _comparable(stdout, tmp_path / "piped") == _comparable(on_tty, tmp_path / "tty")
    assert not BAR.search(stdout) and "search: 4/4 local solves" in stdout


@pytest.mark.slow  # two diagnoses of a small case: about a minute on 2 cores
def test_diagnose_shows_stage_round_and_elapsed_time_on_a_terminal_only(tmp_path):
    """Under a terminal the diagnosis bar names the stage running, the round, n/N stages and
    the time elapsed (no remaining time: the stages take unequal times), and the round's
    refits their count with elapsed < remaining. Piped, stderr stays empty and stdout holds
    the same lines."""
    coupled_case(tmp_path)
    args = ["diagnose", str(tmp_path / "case.yaml")]
    stdout, err = _under_pty(args, tmp_path / "tty", timeout=600)
    text = re.sub(r"\x1b\[[0-9;]*[A-Za-z]", "", err)
    for name in ("baseline", "selection, round 1 of at most 3", "checks", "verdict"):
        assert re.search(rf"diagnose: {name}: +\d+%\|.*\| \d/\d+ \[\d\d:\d\d elapsed\]", text), name
    assert re.search(r"candidate refits: +\d+%\|.*\| (\d+)/\1 \[\d\d:\d\d<\d\d:\d\d", text)
    assert not BAR.search(stdout) and "verdict: missing_physics" in stdout
    piped, stderr = _piped(ROOT, args, tmp_path / "piped", timeout=600)
    assert stderr == ""
    assert _comparable(piped, tmp_path / "piped") == _comparable(stdout, tmp_path / "tty")


class _Terminal(io.StringIO):
    def isatty(self):
        return True

    def fileno(self):   # no size: the bar falls back to 100 columns
        raise io.UnsupportedOperation


def test_reporters_draw_on_a_terminal_and_do_nothing_elsewhere(monkeypatch):
    lines = []
    log = lines.append
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    with progress.stage("quiet", 3) as bar:
        bar.update(best_f="1")
        bar.note("a note")
        assert bar.around(log) is log
    assert sys.stderr.getvalue() == ""
    tty = _Terminal()
    monkeypatch.setattr(sys, "stderr", tty)
    with progress.steps("diagnose", 2) as bar:
        progress.advance("diagnose", "screen")
        progress.advance("diagnose", "baseline")
        progress.advance("diagnose", "baseline, round 1", step=False)
        progress.advance("diagnose", "verdict")     # a further look: the total grows
        bar.around(log)("a log line")
    progress.advance("diagnose", "after")           # no bar open: nothing happens
    text = tty.getvalue()
    assert "diagnose: baseline, round 1" in text and "3/3 [" in text
    assert re.search(r"3/3 \[\d\d:\d\d elapsed\]", text)   # steps: no remaining time
    assert lines == ["a log line"]


def test_a_closed_bar_shows_its_final_count_after_updates_within_mininterval(monkeypatch):
    """Updates that arrive together (parallel workers' results) fall within tqdm's mininterval
    of the last drawing; closing the bar still draws n/N."""
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    outer = progress._Bar("diagnose", 9, "step", 0)   # a nested bar is cleared when closed
    bar = progress._Bar("candidate refits", 6, "refit", 0)
    for _ in range(6):
        bar.update()          # all within 0.2 s: only the first is drawn by tqdm itself
    bar.close()
    outer.close()
    assert "6/6" in err.getvalue()
