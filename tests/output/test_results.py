"""Result files of large models: M, K, C go to a sparse NPZ instead of the JSON."""

import json
import os

import numpy as np
import scipy.sparse as sp

from nlp.output.results import MATRIX_MAX, load_matrices, with_matrix_file, write_json


def test_large_matrices_go_to_a_sparse_npz_and_read_back(tmp_path):
    n = MATRIX_MAX + 1
    rng = np.random.default_rng(0)
    mats = {lab: {k: sp.random(n, n, density=0.01, random_state=rng).toarray() for k in "MKC"}
            for lab in ("initial", "updated")}
    doc = {"case": "x", "matrices": mats}
    out = with_matrix_file(doc, "matrices", str(tmp_path))
    assert out["matrices"]["file"] == "matrices.npz" and doc["matrices"] is mats  # doc unchanged
    write_json(str(tmp_path / "result.json"), out)
    assert os.path.getsize(tmp_path / "result.json") < 2000
    back = load_matrices(str(tmp_path / "matrices.npz"))
    for lab in mats:
        for k in "MKC":
            assert np.array_equal(back[lab][k].toarray(), mats[lab][k])
    # one model (summary.json's form), and a small model stays in the JSON
    one = with_matrix_file({"model": mats["updated"]}, "model", str(tmp_path), name="model.npz")
    assert np.array_equal(load_matrices(str(tmp_path / "model.npz"))["K"].toarray(),
                          mats["updated"]["K"])
    assert one["model"]["n"] == n
    small = {"matrices": {"updated": {k: np.eye(3) for k in "MKC"}}}
    assert with_matrix_file(small, "matrices", str(tmp_path)) is small
    assert json.loads(json.dumps(small, default=lambda a: a.tolist()))["matrices"]["updated"]["M"][0] == [1, 0, 0]
