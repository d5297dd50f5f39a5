"""The figures the README and the docs show have one source: ``benchmarks/results/*.json``, rendered into their
tables by ``benchmarks/tables.py`` (JSON in, Markdown out; no tumble, no numba)."""

import importlib.util
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_SPEC = importlib.util.spec_from_file_location("benchmark_tables", ROOT / "benchmarks" / "tables.py")
tables = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(tables)


def test_every_table_of_the_readme_and_the_docs_is_what_the_results_files_give():
    assert not tables.stale(), ("tables that differ from benchmarks/results/*.json (run python "
                                f"benchmarks/tables.py): {tables.stale()}")


def test_every_results_file_says_its_machine_vector_width_date_and_commit():
    for path in sorted((ROOT / "benchmarks" / "results").glob("*.json")):
        data = json.loads(path.read_text(encoding="utf-8"))
        missing = [key for key in ("machine", "vector_width", "date", "commit") if not data.get(key)]
        assert not missing, f"{path.name} lacks {missing}"
        assert data["vector_width"] in ("AVX-512", "AVX2", "unknown"), path.name


def test_every_page_has_its_headline_table_and_names_only_known_tables():
    for page in tables.PAGES:
        text = (ROOT / page).read_text(encoding="utf-8")
        names = [m["name"] for m in tables._MARKED.finditer(text)]
        assert names, f"{page} has no table"
        assert set(names) <= set(tables.TABLES), page
    for page in ("README.md", "docs/index.md"):
        assert "<!-- tables:begin headline -->" in (ROOT / page).read_text(encoding="utf-8")


def test_the_check_names_a_stale_table_and_exits_1(tmp_path, monkeypatch, capsys):
    page = tmp_path / "page.md"
    fresh, _ = tables.render("<!-- tables:begin engine -->\n<!-- tables:end engine -->\n", "")
    page.write_text(fresh.replace("| `rk4` |", "| `rk4` (edited) |"), encoding="utf-8")
    monkeypatch.setattr(tables, "ROOT", tmp_path)
    monkeypatch.setattr(tables, "PAGES", {"page.md": ""})
    assert tables.main(["--check"]) == 1
    assert "page.md: engine" in capsys.readouterr().err
    assert tables.main([]) == 0 and tables.main(["--check"]) == 0
    assert page.read_text(encoding="utf-8") == fresh


def test_a_table_of_an_unknown_name_is_refused():
    with pytest.raises(KeyError, match="no table named 'nothing'"):
        tables.render("<!-- tables:begin nothing -->\n<!-- tables:end nothing -->\n", "")
