"""A weakly identified direction: starts that crawl to the iteration limit on one
objective value beat a start that converged higher (nlp.solve.search.agreed_minimum)."""

import numpy as np

from nlp.solve.problem import LocalResult
from nlp.solve.search import agreed_minimum

LIMIT = "Maximum_Iterations_Exceeded"


def _r(f, status, success):
    return LocalResult(z=np.zeros(2), f=f, success=success, status=status, iterations=500,
                       seconds=0.0)


def test_agreeing_limit_starts_win_over_a_higher_converged_one():
    res = [_r(0.141657, LIMIT, False), _r(16.16, "Solve_Succeeded", True),
           _r(0.141662, LIMIT, False), _r(0.141655, LIMIT, False), _r(321.9, LIMIT, False)]
    assert agreed_minimum(res, list(range(5))) == [0, 2, 3]


def test_no_agreement_keeps_the_converged_best():
    # two limit starts only, or limit starts that disagree, or a converged start as low
    two = [_r(0.1, LIMIT, False), _r(0.1, LIMIT, False), _r(1.0, "Solve_Succeeded", True)]
    spread = [_r(0.10, LIMIT, False), _r(0.11, LIMIT, False), _r(0.12, LIMIT, False),
              _r(1.0, "Solve_Succeeded", True)]
    as_low = [_r(0.1, LIMIT, False)] * 3 + [_r(0.1, "Solve_Succeeded", True)]
    failed = [_r(0.1, "Invalid_Number_Detected", False)] * 3 + [_r(1.0, "Solve_Succeeded", True)]
    for res in (two, spread, as_low, failed):
        assert agreed_minimum(res, list(range(len(res)))) == []
