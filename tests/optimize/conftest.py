"""A run directory with report.html, shared by the report tests (one run per test session)."""

import pytest


def contact_problem():
    """The punch-on-block design problem (contact; a designed body and an undesigned one)."""
    from contopt.cases.two_blocks import two_blocks
    from contopt.design import BSplineGrid, Design, DesignedBody
    from contopt.optimize.problem import DesignProblem
    from contopt.responses import StrainEnergy

    design = Design(DesignedBody("block", BSplineGrid((2, 2, 1)), volume_fraction=0.5))
    return DesignProblem(model=two_blocks(), design=design, objective=-StrainEnergy())


@pytest.fixture(scope="session")
def report_problem():
    """The design problem report_run optimizes (its facts are what report.html's summary says)."""
    return contact_problem()


@pytest.fixture(scope="session")
def report_run(tmp_path_factory, report_problem):
    """(run directory, OptimizationResult) of two MMA iterations, VTU every iteration, pictures drawn,
    with the problem's summary in words kept as a problem file's run keeps it (RunSpec.run)."""
    from contopt.cases.problem_summary import problem_summary, record_summary
    from contopt.optimize.driver import optimize
    from contopt.optimize.mma import MMAOptions

    out = tmp_path_factory.mktemp("report_run")
    sentences = problem_summary(report_problem)
    res = optimize(
        report_problem, "mma", MMAOptions(max_iter=2), out=out, started=lambda d: record_summary(d, sentences)
    )
    return out, res
