"""The study file described once (tumble.pipeline.schema): the defaults file, config's checks, the docs' reference
and the runner's scene options all follow the description."""

import copy
import math
import sys
import tomllib
from pathlib import Path

import pytest

from tumble.pipeline import config, runner, schema
from tumble.pipeline.config import StudyError, load_study

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "docs" / "_ext"))
import tumble_docs  # the docs' Sphinx extension, importable without Sphinx running

DESCRIBED = [f for f in schema.FIELDS if f.in_defaults]


def test_the_defaults_file_is_the_rendering_of_the_description():
    """Regenerate with ``python -m tumble.pipeline.schema`` after changing a field."""
    assert config.DEFAULTS_PATH.read_text(encoding="utf-8") == schema.defaults_toml()
    assert schema.main(["--check"]) == 0


def test_every_key_of_the_defaults_file_is_described_and_every_described_key_is_there():
    defaults = tomllib.loads(config.DEFAULTS_PATH.read_text(encoding="utf-8"))
    in_file = [t if not isinstance(v, dict) else f"{t}.{k}" for t, v in defaults.items()
               for k in (v if isinstance(v, dict) else [None])]
    assert in_file == [f.path for f in DESCRIBED]
    assert defaults == schema.defaults()
    assert list(defaults) == ["title", *schema.TABLES]


def test_config_allows_exactly_the_described_keys_in_the_described_order():
    assert config._TABLES == schema.TABLES
    assert config.SCAN_KEYS == {f.key: f.replaces for f in schema.table_fields("scan")}
    resolved = load_study({})
    for table in ("body", "perturbation", "integration", "torque", "outputs"):
        assert list(resolved[table]) == list(schema.TABLES[table])


def test_every_described_field_has_a_doc_and_every_numeric_one_units():
    for f in DESCRIBED:
        assert f.doc.strip() and f.doc.endswith("\n"), f.path
        default = f.default
        numeric = (isinstance(default, (int, float)) and not isinstance(default, bool)) or (
            isinstance(default, list) and default and all(isinstance(v, (int, float)) for v in default))
        assert not numeric or f.units or f.path == "spin.momentum", f.path
        if f.choices is not None:
            assert default in f.choices or isinstance(default, list) and set(default) <= set(f.choices), f.path


def _with(field, value):
    study = {field.table: {field.key: value}} if field.table else {field.key: value}
    if field.table == "model" and field.key != "kind":  # a kind's own parameter, only with that kind
        owner = next(m.name for m in config.registry.MODELS
                     if field.key in (*m.parameters, *config.models.CLASSES[m.name].extras))
        study["model"]["kind"] = owner
        if owner == "heavy_top":
            study["model"].setdefault("mgl", 1.0)
            study["spin"] = {"axis": 3}
        elif owner == "gravity_gradient":
            study["model"].setdefault("orbit_rate", 1.0)
    if field.table == "chaos" and field.key != "indicators":  # used by a chaos study only: a whole one
        study = {"model": {"kind": "heavy_top", "mgl": 1.0}, "integration": {"dt": 0.01, "horizon": 1.0},
                 "chaos": {"indicators": ["megno"], field.key: value}, "scan": {"tilt": [0.1, 0.2], "rate": [1.0]}}
    if field.table == "section" and field.key not in ("surface", "period"):  # used by a section only: a whole one
        study = {"model": {"kind": "heavy_top", "mgl": 1.0}, "integration": {"method": "dop853", "horizon": 1.0},
                 "scan": {"tilt": [0.1, 0.2], "rate": [1.0]}, "section": {"surface": "g1", field.key: value}}
    return study


@pytest.mark.parametrize("field", DESCRIBED, ids=lambda f: f.path)
def test_every_described_field_is_accepted_at_its_default_and_refused_malformed_naming_it(field):
    load_study(_with(field, copy.deepcopy(field.default)) if field.table != "model" or field.key == "kind"
               else {})
    malformed = {"title": 3, "body.dimensions": [1]}.get(field.path, {"bad": "table"})
    with pytest.raises(StudyError) as refused:
        load_study(_with(field, malformed))
    assert str(refused.value).startswith("<mapping>: ") and refused.value.field.startswith(field.path)


@pytest.mark.parametrize("field", [f for f in DESCRIBED if f.check in ("choice", "names")], ids=lambda f: f.path)
def test_a_described_choice_is_refused_outside_its_values_with_the_values_listed(field):
    value = "nonesuch" if field.check == "choice" else ["nonesuch"]
    path = field.path if field.check == "choice" else f"{field.path}[0]"
    with pytest.raises(StudyError, match=r"unknown value 'nonesuch'") as refused:
        load_study(_with(field, value))
    assert refused.value.field == path
    assert all(repr(v) in refused.value.problem for v in field.choices)


@pytest.mark.parametrize("field", [f for f in DESCRIBED if f.minimum is not None and f.check in ("integer", "number")],
                         ids=lambda f: f.path)
def test_a_described_bound_is_refused_below_it(field):
    below = field.minimum - 1 if field.check == "integer" else -0.5
    with pytest.raises(StudyError, match=rf"must be >= {field.minimum:g}"):
        load_study(_with(field, below))


def test_the_docs_reference_lists_every_described_field_with_its_units_and_values():
    text = tumble_docs.study_reference(config.DEFAULTS_PATH)
    rows = {line.split("|")[1].strip().strip("`"): line for line in text.splitlines() if line.startswith("| `")}
    assert sorted(rows) == sorted(f"scan.{f.key}" if f.table == "scan" else f.path for f in schema.FIELDS)
    for f in DESCRIBED:
        cells = [cell.strip() for cell in rows[f.path].split("|")[1:-1]]
        assert cells[2] == f.units.replace("|", "\\|"), f.path
        if f.choices:
            assert all(f"`{v!r}`" in cells[3] for v in f.choices), f.path
    for f in schema.table_fields("scan"):
        assert f"`{f.replaces}`" in rows[f"scan.{f.key}"]


def test_the_scene_options_are_the_described_options_of_the_study():
    resolved = load_study({"integration": {"dt": 0.01, "flips": 2}, "perturbation": {"distribution": "gaussian"}})
    options = runner.plan(resolved).options
    described = {f.option for f in schema.FIELDS if f.option}
    assert described <= set(options)
    assert options["dt"] == 0.01 and options["flips"] == 2 and options["distribution"] == "gaussian"
    assert options["horizon"] is None  # 0: the planner's choice
    assert options["device"] == "cpu"


def test_the_toml_writer_gives_back_every_default():
    for f in DESCRIBED:
        text = f"x = {schema._toml(f.default)}"
        assert tomllib.loads(text)["x"] == f.default, f.path
    assert schema._toml(1e-3) == "1e-3" and schema._toml(0.5) == "0.5" and math.isclose(
        tomllib.loads(f"x = {schema._toml(1 / 3 * 1e-5)}")["x"], 1 / 3 * 1e-5, rel_tol=0, abs_tol=0)
