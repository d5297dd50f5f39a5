"""The documentation's figures: every figure a tutorial or the chaos-maps page shows exists, every tutorial shows at
least one, the first tutorial shows the study file it runs, and the figure script (``python docs/figures.py``) draws
each of its figures, here at a tiny size."""

import importlib.util
import re
from pathlib import Path

import pytest
from matplotlib.figure import Figure

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
TUTORIALS = sorted((DOCS / "tutorials").glob("*.md"))
CHAOS_PAGES = [DOCS / "tutorials" / "regular-or-chaotic.md", DOCS / "explanation" / "chaos-maps.md"]

# A MyST figure or image directive, or a Markdown image: the path it shows.
_FIGURE = re.compile(r"^```\{(?:figure|image)\}\s+(\S+)|!\[[^\]]*\]\(([^)\s]+)", re.M)


def _figure_script():
    spec = importlib.util.spec_from_file_location("doc_figures", DOCS / "figures.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _figures(page):
    """The files ``page`` shows as figures, resolved from the page's folder."""
    text = page.read_text(encoding="utf-8")
    return [(page.parent / (a or b)).resolve() for a, b in _FIGURE.findall(text)]


FIGURES = _figure_script().FIGURES

# Each figure at a size that runs in well under a second once numba's cache is warm.
TINY = {
    "megno_against_time": {"horizon": 2.0, "dt": 0.1, "points": 2},
    "lyapunov_against_time": {"horizon": 4.0, "dt": 0.1, "save_every": 10},
    "gali_against_time": {"horizon": 2.0, "dt": 0.1, "save_every": 10},
    "integrator_error": {"t_end": 0.5, "dt": 0.05, "save_every": 2},
    "gpu_ensemble": {"t_end": 0.5, "dt": 0.05, "save_every": 2, "samples": 2},
}


def test_every_figure_a_tutorial_or_the_chaos_maps_page_shows_exists():
    shown = {page.relative_to(DOCS).as_posix(): _figures(page) for page in {*TUTORIALS, *CHAOS_PAGES}}
    missing = [f"{page}: {path}" for page, paths in shown.items() for path in paths if not path.is_file()]
    assert not missing, "figures that are not there:\n" + "\n".join(missing)


def test_every_tutorial_shows_a_figure():
    assert TUTORIALS
    assert not [page.name for page in TUTORIALS if not _figures(page)]


def test_the_chaos_pages_show_megno_and_lyapunov_against_time_and_a_map_with_the_command_that_draws_them():
    for page in CHAOS_PAGES:
        names = {path.name for path in _figures(page)}
        assert "megno_against_time.png" in names and "chaos_map_megno_map.png" in names, (page.name, names)
        assert names & {"lyapunov_against_time.png", "chaos_map_finite_time.png"}, (page.name, names)
        assert "python docs/figures.py" in page.read_text(encoding="utf-8"), page.name


def test_the_script_s_every_figure_is_drawn_and_shown():
    shown = {path for page in DOCS.rglob("*.md") if "_build" not in page.parts for path in _figures(page)}
    for name in FIGURES:
        path = DOCS / "images" / f"{name}.png"
        assert path.is_file(), f"{path.relative_to(ROOT)}: run python docs/figures.py {name}"
        assert path.resolve() in shown, f"{name}.png is on no page"


def test_the_first_tutorial_shows_the_study_file_it_runs():
    text = (DOCS / "tutorials" / "first-study.md").read_text(encoding="utf-8")
    include = re.search(r"^```\{literalinclude\}\s+(\S+)\n:language: toml", text, re.M)
    assert include, "no literalinclude of a TOML study file"
    assert (DOCS / "tutorials" / include.group(1)).resolve() == ROOT / "studies" / "intermediate_axis.toml"


@pytest.mark.parametrize("name", sorted(TINY))
def test_a_figure_of_the_script_draws_at_a_tiny_size(name):
    assert set(TINY) == set(FIGURES)
    figure = FIGURES[name](**TINY[name])
    assert isinstance(figure, Figure)
    lines = [line for ax in figure.axes for line in ax.get_lines()]
    assert lines and all(len(line.get_xdata()) for line in lines)
