"""The report's sentences from a run's records (contopt.optimize.report_story), for each status."""

import json

from contopt.optimize.report_story import (
    PROBLEM_SUMMARY,
    file_links,
    next_command,
    problem_sentences,
    problem_source,
    recorded_summary,
    result_sentence,
    status_sentence,
)


def test_the_next_command_resumes_with_more_iterations_and_never_overwrites():
    line = "contopt run die-slab --mesh coarse --max-iter 2 --out 'my runs/a' --overwrite"
    assert next_command(line, "--resume", "--max-iter", "40") == (
        "contopt run die-slab --mesh coarse --out 'my runs/a' --resume --max-iter 40"
    )
    assert next_command("contopt run x.toml --max-iter=3 --resume", "--resume") == "contopt run x.toml --resume"
    assert next_command(None, "--resume") is None


def test_each_status_in_words():
    line = "contopt run cantilever --max-iter 30"
    converged = {"status": "converged", "message": "KKT residual 4e-05 < kkt_tol 5e-05", "iterations": 7}
    assert (
        status_sentence(converged, line, None)
        == "Converged after 7 iterations (KKT residual 4e-05 &lt; kkt_tol 5e-05)."
    )
    stopped = status_sentence({"status": "max_iter", "message": "", "iterations": 30}, line, None)
    assert "(30 iterations)" in stopped and "contopt run cantilever --resume --max-iter 60" in stopped
    failed = status_sentence({"status": "failed", "message": "the analysis of design 7 failed: Newton"}, line, None)
    assert failed.startswith("Failed") and "design 7" in failed
    unfinished = status_sentence(None, line, 4)
    assert unfinished.startswith("Not finished") and "contopt run cantilever --resume" in unfinished


def test_a_maximized_response_reads_as_its_positive_share_and_a_minimized_one_as_its_value():
    maximized = {
        "objective": -0.04744,
        "objective_scale": 0.0502,
        "normalize": "full",
        "volume_fractions": {"slab": 0.3997},
    }
    text = result_sentence(maximized, {"objective": "-strain_energy[slab]"})
    share = "strain energy of slab (maximized): 94.5 % of the full design&#x27;s (0.04744)"
    assert text == share + ", with 40.0 % of slab&#x27;s volume."
    minimized = {"objective": 2.5, "objective_scale": 2.0, "normalize": "initial", "volume_fractions": {}}
    assert result_sentence(minimized, {"objective": "compliance"}).startswith(
        "compliance (minimized): 125.0 % of the initial design"
    )
    fixed = {"objective": 2.5, "objective_scale": 1.0, "normalize": "7.0", "volume_fractions": {"a": 0.25}}
    assert (
        result_sentence(fixed, {"objective": "compliance"})
        == "compliance (minimized): 2.5, with 25.0 % of a&#x27;s volume."
    )
    assert result_sentence(None, {}) == ""


def test_links_name_only_the_files_that_exist_and_the_problem_is_escaped(tmp_path):
    assert file_links(tmp_path) == "" and problem_source(tmp_path) == ""
    (tmp_path / "history.csv").write_text("iteration\n")
    (tmp_path / "problem.toml").write_text('name = "<b>"\n')
    links = file_links(tmp_path)
    assert 'href="history.csv"' in links and 'href="problem.toml"' in links and "design.stl" not in links
    assert "&lt;b&gt;" in problem_source(tmp_path) and "<b>" not in problem_source(tmp_path)


def test_the_problem_in_words_is_escaped_and_a_missing_one_is_said(tmp_path):
    assert recorded_summary(tmp_path) is None
    (tmp_path / "checkpoint").mkdir()
    sentences = [
        {"topic": "bodies", "text": "One body: <b> & co (hex8, 8 cells)."},
        {"topic": 'x"onclick="y', "text": "Objective: minimize the compliance of <b>."},
    ]
    (tmp_path / PROBLEM_SUMMARY).write_text(json.dumps(sentences))
    assert recorded_summary(tmp_path) == sentences
    shown = problem_sentences(recorded_summary(tmp_path))
    assert shown.startswith('<ul class="problem-summary" id="problem-summary"><li data-topic="bodies">')
    assert "One body: &lt;b&gt; &amp; co (hex8, 8 cells)." in shown and "<b>" not in shown
    assert 'data-topic="x&quot;onclick=&quot;y"' in shown
    (tmp_path / PROBLEM_SUMMARY).write_text("{not json")
    for missing in (recorded_summary(tmp_path), None, "text", [{"topic": "bodies"}], [3]):
        note = problem_sentences(missing)
        assert note.startswith('<p class="note" id="problem-summary">') and "not recorded" in note
