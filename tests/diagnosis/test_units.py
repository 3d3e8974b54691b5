"""A finding's parameters in physical units (nlp.diagnosis.units): conversions and their
first-order standard errors against a finite difference, and labels that depend on the model."""

import math

from nlp.diagnosis.units import describe, quantities, quantity


def test_log10_parameter_converts_with_its_relative_error():
    v, se = 5.941, 0.029
    q = quantity("base_flexibility", "log10_kb", v, se)
    assert math.isclose(q.value, 10.0 ** v, rel_tol=1e-12)
    h = 1e-6   # first-order propagation: |d(10^v)/dv| se / 10^v by a central difference
    fd = (10.0 ** (v + h) - 10.0 ** (v - h)) / (2 * h) * se / 10.0 ** v
    assert math.isclose(q.relative_se, fd, rel_tol=1e-6)
    assert describe(q).startswith("k_b = 8.73e5 N/m (± 6.7 %)")


def test_inverse_parameter_keeps_its_relative_error():
    q = quantity("frame_action", "rho_inv", 0.5, 0.05)
    assert math.isclose(q.value, 2.0) and math.isclose(q.relative_se, 0.1)


def test_base_dashpot_is_labelled_beyond_the_law_only_under_rayleigh_damping():
    f = {"physics": "base_flexibility", "parameters": {"m_base": 3e4, "c_base": 1.4e4},
         "uncertainty": {"m_base": 50.0, "c_base": 7e3}}
    labels = dict((n, q.label) for n, q in quantities(f, {"rayleigh": True}))
    assert labels["c_base"] == "base dashpot beyond the Rayleigh law"
    assert labels["m_base"] == "base mass"
    general = dict((n, q.label) for n, q in quantities(f, {"rayleigh": False}))
    assert general["c_base"] == "base dashpot"
    assert dict(quantities(f))["c_base"].label == "base dashpot"


def test_appendage_mass_ratio_names_its_reference_mass():
    """On a model without floors (an FE matrix export) m_ref is the mean mass at the channels'
    DOFs: the ratio says so, and m_s = mu m_ref either way."""
    f = {"physics": "secondary_oscillator", "parameters": {"mu": 0.157, "f_s": 2.11},
         "uncertainty": {"mu": 0.013, "f_s": 0.008}}
    for refs, label in (({"m_ref": 12000.0, "channel_masses": True},
                         "appendage mass ratio to the mean mass at the channels' DOFs"),
                        ({"m_ref": 12000.0}, "appendage mass ratio to the mean floor mass")):
        qs = quantities(f, refs)
        assert qs[0][1].label == label
        m_s = [q for _, q in qs if q.symbol == "m_s"][0]
        assert math.isclose(m_s.value, 0.157 * 12000.0)
        assert math.isclose(m_s.relative_se, 0.013 / 0.157)
