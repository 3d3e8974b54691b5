"""The verdict's rule for findings of the set-up only (a channel's gain or delay): the
structure is adequate and the case's sensors are not as it says (nlp.diagnosis.verdict)."""

from nlp.diagnosis.plain import paragraph
from nlp.diagnosis.verdict import classify

GAIN = {"physics": "sensor_gain", "location": {"channel": "a3"},
        "parameters": {"gain_a3": 0.035}, "uncertainty": {"gain_a3": 0.002}}
DELAY = {"physics": "sensor_delay", "location": {"channel": "d2"},
         "parameters": {"delay_ms_d2": -9.1}, "uncertainty": {"delay_ms_d2": 0.03}}
MASS = {"physics": "added_mass", "location": {"floor": 2}}


def test_gains_and_delays_alone_are_a_setup_error():
    assert classify([GAIN], [], [], False, [DELAY], False) == "setup_error"
    assert classify([], [], [], False, [DELAY], True) == "setup_error"


def test_a_structural_finding_beside_them_is_missing_physics():
    assert classify([GAIN, MASS], [], [], False, [DELAY], False) == "missing_physics"
    # a level dependence is structural, whatever else is found
    assert classify([GAIN], [], [], True, [], False) == "missing_physics"


def test_what_they_leave_unexplained_keeps_the_verdict_partial():
    assert classify([GAIN], [], [], False, [], False, remaining=True) == "partly_explained"
    assert classify([GAIN], [], [], False, [], False, discrepancy=True) == "partly_explained"


def test_nothing_found_is_not_a_setup_error():
    assert classify([], [], [], False, [], True) == "adequate"
    assert classify([], [], [], False, [], False) == "ambiguous"


def test_the_paragraph_says_the_set_up_is_to_be_corrected_not_the_model():
    d = {"verdict": "setup_error", "findings": [GAIN, DELAY],
         "fit": {"before": {"reduced_chi2": 8.9, "held_out_chi2": 4.5},
                 "after": {"reduced_chi2": 1.1, "held_out_chi2": 1.2}}}
    text = paragraph(d)
    assert text.startswith("The structural model is adequate")
    assert "a3" in text and "d2" in text and "not the model" in text
    # the screening's set-up error (the data contradict the case) keeps its own words
    assert paragraph({"verdict": "setup_error", "findings": []}).startswith(
        "The data contradict the case's set-up")
