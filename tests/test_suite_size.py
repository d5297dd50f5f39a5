"""The README's test command holds its size, file by file (issue 58: the default run is the one a newcomer waits for).

Each test file has a budget of test cases the default run (``-m 'not slow'``) may collect from it: the counts
when the suite last met its time target. A file that grows past its budget fails here, naming it: mark the new
combinatorial cases with ``@pytest.mark.default_cases(...)`` (one case proves the path, the slow run keeps the
breadth) or ``@pytest.mark.slow``, or raise the budget below in the same commit, saying in its message what the
warm run costs now. A new test file needs a budget too.
"""

from collections import Counter
from pathlib import Path

#: Default-run test cases per file, at most.
BUDGET = {
    "test_adaptive.py": 22,
    "test_analysis.py": 91,
    "test_attitude.py": 43,
    "test_attitude_plots.py": 24,
    "test_bodies.py": 28,
    "test_bundled_results.py": 17,
    "test_chaos.py": 77,
    "test_chaos_studies.py": 33,
    "test_chaos_tolerance.py": 12,
    "test_check.py": 46,
    "test_checked_once.py": 19,
    "test_cli.py": 76,
    "test_codegen.py": 2,
    "test_config.py": 182,
    "test_cuda.py": 29,
    "test_cuda_models.py": 16,
    "test_distributed.py": 22,
    "test_doc_figures.py": 10,
    "test_docs.py": 22,
    "test_docstrings.py": 9,
    "test_elliptic.py": 34,
    "test_elliptic_vectorised.py": 37,
    "test_engine.py": 19,
    "test_engines.py": 6,
    "test_exact.py": 106,
    "test_exact_attitude.py": 8,
    "test_faults.py": 13,
    "test_first_call.py": 5,
    "test_integrators.py": 102,
    "test_io.py": 26,
    "test_kind_names.py": 5,
    "test_latency.py": 39,
    "test_layers.py": 146,
    "test_layout.py": 60,
    "test_memory.py": 1,
    "test_model_equations.py": 6,
    "test_model_fast_paths.py": 14,
    "test_model_kernels.py": 57,
    "test_model_kernels_gravity_gradient_damper.py": 27,
    "test_model_splittings.py": 31,
    "test_model_studies.py": 73,
    "test_model_studies_gravity_gradient_damper.py": 37,
    "test_models.py": 55,
    "test_models_gravity_gradient_damper.py": 42,
    "test_plots.py": 66,
    "test_precision.py": 16,
    "test_propagate.py": 17,
    "test_readme.py": 4,
    "test_resume.py": 29,
    "test_robustness.py": 153,
    "test_sampling.py": 146,
    "test_scene_kinds.py": 4,
    "test_schema.py": 81,
    "test_section_studies.py": 24,
    "test_sections.py": 22,
    "test_shapes.py": 96,
    "test_stress.py": 38,
    "test_study.py": 54,
    "test_suite_size.py": 1,
    "test_system_blocks.py": 12,
    "test_system_kernels.py": 25,
    "test_tables.py": 5,
    "test_tangent_blocks.py": 2,
    "test_theory.py": 69,
    "test_threads.py": 3,
    "test_trig.py": 28,
    "test_user_systems.py": 45,
    "test_warm.py": 2,
}


def test_each_test_file_keeps_within_its_budget_of_default_cases(request):
    """Counted from this session's own items (what the run collected and did not deselect: with ``-m 'not slow'``, the
    default run's cases; a run of some files counts those)."""
    counts = Counter(Path(str(item.fspath)).name for item in request.session.items)
    over = {name: (count, BUDGET.get(name)) for name, count in counts.items() if count > BUDGET.get(name, 0)}
    assert not over, ("default cases (collected, budget) over the budget of tests/test_suite_size.py, by file: "
                      f"{over}")
