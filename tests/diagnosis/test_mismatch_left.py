"""Where a partly explained mismatch sits: the fitted band's misfit first, and a misfit above
the fitted band (where the model was never fitted) said to be there."""

from nlp.diagnosis.plain import beyond_fit, paragraph
from nlp.diagnosis.verdict import left_statement, mismatch_left


def _whole():
    # fitted 4-40 Hz (cells with fitted points); 67-83 Hz only in the whole-band map
    rows = [("floor1", [4.0, 12.0], 1.1, 20), ("floor2", [12.0, 40.0], 9.0, 30),
            ("floor3", [12.0, 40.0], 3.0, 30), ("floor3", [66.8, 83.0], 215.0, 0)]
    after = [{"channel": ch, "band_hz": band, "chi2": chi2, "points": 100, "fitted_points": n}
             for ch, band, chi2, n in rows]
    return {"map": {"after": after}, "extra_modes": []}


def test_the_fitted_band_comes_first_and_beyond_it_is_named():
    left = mismatch_left(_whole())
    assert left["fitted_band_hz"] == [4.0, 40.0]
    # the 1.1 cell is under the limit (2); in-band worst first, then the cell beyond the band
    assert [(c["channel"], c["chi2"]) for c in left["cells"]] == \
        [("floor2", 9.0), ("floor3", 3.0), ("floor3", 215.0)]
    assert [beyond_fit(c, left["fitted_band_hz"]) for c in left["cells"]] == [False, False, True]
    st = left_statement(left)
    assert "floor2 at 12.0-40.0 Hz (9 x the noise)" in st
    assert "floor3 at 66.8-83.0 Hz (215 x the noise, beyond the fitted band)" in st
    words = paragraph({"verdict": "partly_explained", "findings": [], "fit": {},
                       "remaining_mismatch": True, "mismatch_left": left})
    assert ("the rest sits mostly on floor2 at 12-40 Hz and floor3 at 12-40 Hz, and beyond "
            "the fitted band on floor3 at 67-83 Hz") in words


def test_a_map_without_fitted_cells_labels_nothing_beyond():
    whole = _whole()
    for c in whole["map"]["after"]:
        c["fitted_points"] = 0
    left = mismatch_left(whole)
    assert left["fitted_band_hz"] is None
    assert left["cells"][0]["chi2"] == 215.0          # worst first, as before
    assert "beyond" not in left_statement(left)
