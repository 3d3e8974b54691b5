"""The search checkpoint: every finished start, appended as it finishes.

A JSON-lines file: a header line (format, a hash of the problem and its start
points, the seed and search settings), then one line per finished start
(index, start point, solution, objective, status). Each line is written with
one ``write`` to a file opened for appending, so a killed run leaves at most
one torn last line, which is ignored on resume. Floats are written with
``repr`` precision, so a resumed search compares exactly the same numbers as
an uninterrupted one.

Where it lives: ``DIR.partial/checkpoint.jsonl`` beside the output folder
``DIR`` (one file per update of a case with several, ``checkpoint-<update>.jsonl``);
the folder is removed when a run completes.
"""

import hashlib
import json
import os

import numpy as np

from nlp.errors import InputError
from nlp.solve.problem import LocalResult

__all__ = ["Checkpoint", "checkpoint_path", "problem_hash"]

FORMAT = "frf-nlp-checkpoint/1"


def checkpoint_path(out, label=None):
    """Where the checkpoint of output folder ``out`` (and update ``label``) lives."""
    root = os.path.abspath(out).rstrip(os.sep) + ".partial"
    return os.path.join(root, f"checkpoint-{label}.jsonl" if label else "checkpoint.jsonl")


def problem_hash(problem, starts):
    """A hash of what decides every start's result: data, bounds, solver and the starts."""
    h = hashlib.sha256()
    lo, hi = problem.bounds
    for a in (problem.data_vector, problem.z0, lo, hi, starts):
        h.update(np.ascontiguousarray(a, dtype=float).tobytes())
    sc = problem.solver_config
    h.update(repr((problem.residual, sc.name, sorted(sc.nlpsol_options().items(), key=str),
                   problem.total_mass)).encode())
    return h.hexdigest()[:32]


def _num(x):
    return float(x) if np.isfinite(x) else None


class Checkpoint:
    """Append-only record of finished starts at ``path``; ``resume`` reads it first."""

    def __init__(self, path, resume=False):
        self.path, self.resume = path, resume
        self._fd = None

    def open(self, problem, config, starts):
        """Start (or continue) the file; returns the finished starts it holds {index: result}.

        With ``resume``, an update whose file is missing beside the checkpoints of
        earlier updates (the run stopped before reaching it) starts afresh.
        """
        header = {"format": FORMAT, "hash": problem_hash(problem, starts), "seed": config.seed,
                  "starts": len(starts), "trial_factor": config.trial_factor,
                  "min_distance": config.min_distance}
        done = {}
        lines = []
        if self.resume and os.path.exists(self.path):
            lines = self._read(header)
        elif self.resume and not os.path.isdir(os.path.dirname(self.path)):
            raise InputError("<arguments>", "--resume", "a checkpoint of an interrupted run at "
                             f"{self.path}; there is none (run without --resume)")
        if lines:
            for rec in lines[1:]:
                i = rec["start"]
                done[i] = LocalResult(z=np.array(rec["z"], float),
                                      f=np.inf if rec["f"] is None else rec["f"],
                                      success=rec["success"], status=rec["status"],
                                      iterations=rec["iterations"], seconds=rec["seconds"],
                                      z0=np.array(rec["z0"], float))
        os.makedirs(os.path.dirname(self.path), exist_ok=True)
        tmp = self.path + ".tmp"
        with open(tmp, "w") as fh:  # header (+ the valid old lines), then rename: atomic
            fh.write(json.dumps(header) + "\n")
            for rec in lines[1:]:
                fh.write(json.dumps(rec) + "\n")
        os.replace(tmp, self.path)
        self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        return done

    def _read(self, header):
        lines = []
        with open(self.path) as fh:
            for line in fh:
                try:
                    lines.append(json.loads(line))
                except ValueError:  # a torn last line from a killed run
                    break
        if not lines or lines[0].get("format") != FORMAT:
            raise InputError(self.path, "format", f"a {FORMAT} checkpoint (delete it to start over)")
        old = lines[0]
        for key in ("seed", "starts", "trial_factor", "min_distance", "hash"):
            if old.get(key) != header[key]:
                what = ("the same case, data and solver options" if key == "hash"
                        else f"search.{key} = {old.get(key)}")
                raise InputError(self.path, key, f"{what} as the interrupted run, got a different "
                                 f"{'problem' if key == 'hash' else header[key]} (run without "
                                 "--resume to start over)")
        return lines

    def append(self, i, res):
        """Record finished start i (one write: a line is either whole or absent)."""
        rec = {"start": int(i), "f": _num(res.f), "success": bool(res.success),
               "status": str(res.status), "iterations": int(res.iterations),
               "seconds": float(res.seconds), "z0": np.asarray(res.z0, float).tolist(),
               "z": [v if np.isfinite(v) else None for v in np.asarray(res.z, float).tolist()]}
        os.write(self._fd, (json.dumps(rec) + "\n").encode())

    def close(self):
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
