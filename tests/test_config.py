"""Study files: the documented defaults, merging, resolution, and one clear error per malformed study."""

import ast
import copy
import json
import math
import pickle
import re
import shutil
import tomllib

import numpy as np
import pytest

import tumble
from tumble.engine import sampling
from tumble.pipeline import config
from tumble.pipeline.config import StudyError, load_study


def write(tmp_path, text, name="study.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def default_study():
    """The defaults resolved as a study (title aside)."""
    return load_study({})


# ------------------------------------------------------------------------------------------------------
# The defaults file


def test_every_default_key_has_a_comment_line_above_it():
    lines = config.DEFAULTS_PATH.read_text(encoding="utf-8").splitlines()
    keys = []
    for i, line in enumerate(lines):
        match = re.match(r"\s*([A-Za-z_][A-Za-z0-9_]*)\s*=", line)
        if match:
            keys.append(match.group(1))
            assert i > 0 and lines[i - 1].lstrip().startswith("#"), f"key {match.group(1)!r} has no comment"
    defaults = tomllib.loads("\n".join(lines))
    leaves = ["title"] + [f"{t}.{k}" for t, table in defaults.items() if isinstance(table, dict) for k in table]
    assert sorted(keys) == sorted(path.rsplit(".", 1)[-1] for path in leaves)


def test_defaults_file_has_every_section_and_key_the_validator_knows():
    defaults = tomllib.loads(config.DEFAULTS_PATH.read_text(encoding="utf-8"))
    assert list(defaults) == list(config._TOP)
    for table, keys in config._TABLES.items():
        expected = () if table == "scan" else keys
        assert tuple(defaults[table]) == expected


def test_defaults_file_documents_every_allowed_name():
    text = config.DEFAULTS_PATH.read_text(encoding="utf-8")
    names = (*config.SHAPES, *config.METHOD_NAMES, *config.PROFILES, *config.FIGURES, *config.FORMATS,
             *config.ARRAYS, *sampling.DISTRIBUTIONS, *config.SCAN_KEYS)
    missing = [name for name in names if not re.search(rf"\b{name}\b", text)]
    assert not missing


def test_defaults_load_and_validate(default_study):
    defaults = tomllib.loads(config.DEFAULTS_PATH.read_text(encoding="utf-8"))
    assert default_study["title"] == config.UNTITLED
    # A free-body study records no [model] table and no spin.momentum (its hash and file are as before the models)
    assert "model" not in default_study and "momentum" not in default_study["spin"]
    # nor a [chaos] table: chaos.indicators = [] (not a chaos map)
    assert "chaos" not in default_study and defaults["chaos"]["indicators"] == []
    assert defaults["model"]["kind"] == "free" and defaults["spin"]["momentum"] == []
    assert "section" not in default_study and defaults["section"]["surface"] == ""  # nor a section
    for table in config._TABLES:
        if table not in ("scan", "model", "chaos", "section"):
            expected = {k: v for k, v in defaults[table].items() if not (table == "spin" and k == "momentum")}
            assert default_study[table] == expected
    assert default_study["scan"] == {}


def test_the_defaults_path_lives_in_the_studies_folder():
    assert config.DEFAULTS_PATH == config.STUDIES_DIR / "defaults.toml"
    assert config.DEFAULTS_PATH.is_file()


def test_named_lists_match_the_packages_that_implement_them():
    from tumble.kernels.loops.methods import METHODS  # imported here: `tumble` imports its subpackages lazily

    assert set(config.METHOD_NAMES) == {"auto", "exact", *METHODS, *tumble.registry.ERROR_CONTROLLED}
    assert all(callable(getattr(tumble.shapes, name)) for name in config.SHAPES)


# ------------------------------------------------------------------------------------------------------
# Merging and resolving


def test_minimal_study_is_the_defaults_plus_its_change(tmp_path, default_study):
    path = write(tmp_path, "[spin]\naxis = 1\n", name="my_study.toml")
    study = load_study(path)
    expected = copy.deepcopy(default_study)
    expected["spin"]["axis"] = 1
    expected["title"] = "my_study"
    assert study == expected


def test_a_string_path_and_a_path_object_give_the_same_study(tmp_path):
    path = write(tmp_path, "title = 'T'\n[perturbation]\nsamples = 8\n")
    assert load_study(str(path)) == load_study(path)
    assert load_study(path)["title"] == "T"


FULL = """
title = "everything at once"
[body]
shape = "cuboid"
dimensions = {mass = 2, a = 0.3, b = 0.2, c = 0.1}
[spin]
axis = 3
rate = -2
[perturbation]
amplitude = 0.01
samples = 64
seed = 7
distribution = "filled_cone"
[integration]
method = "rk8"
dt = 1e-3
horizon = 40
flips = 0
[torque]
profile = "sine"
vector = [0, 0, 1e-3]
period = 2.5
[scan]
amplitude = [1e-4, 1e-3]
method = ["rk4", "splitting4"]
rate = [1, 2.5]
[outputs]
figures = []
format = ["pdf", "png"]
arrays = ["sample_rate", "sample_status"]
directory = "out/here"
"""


SCAN_BODY = """
[scan]
body = [{shape = "rod", dimensions = {mass = 1.0, length = 0.5, radius = 0.01}, label = "rod"},
        {moments = [1, 2, 3], label = "brick"},
        {shape = "cuboid", dimensions = {mass = 2, a = 0.3, b = 0.2, c = 0.1}},
        {moments = [1, 1.5, 1.7]}]
"""


@pytest.mark.parametrize("text", ["[spin]\naxis = 1\n", FULL, "[scan]\ntriangle = 5\n",
                                  "[scan]\nmoments = [[1, 2, 3], [1, 1.5, 1.7]]\n",
                                  "[body]\nshape = 'rod'\ndimensions = {mass = 1, length = 2, about = 'end'}\n",
                                  "[body]\nshape = 't_handle'\n[torque]\nprofile = 'ramp'\nvector = [0, 1e-3, 0]\n"
                                  "duration = 3\n", SCAN_BODY])
def test_a_resolved_study_resolves_to_itself_and_survives_json(tmp_path, text):
    study = load_study(write(tmp_path, text))
    assert load_study(study) == study
    again = json.loads(json.dumps(study))
    assert again == study
    assert load_study(again) == study


def test_resolved_values_are_plain_python_types(tmp_path):
    study = load_study(write(tmp_path, FULL))

    def walk(value):
        if isinstance(value, dict):
            assert all(type(k) is str for k in value)
            for v in value.values():
                walk(v)
        elif isinstance(value, list):
            for v in value:
                walk(v)
        else:
            assert type(value) in (str, int, float), value

    walk(study)
    assert study["spin"]["rate"] == -2.0 and type(study["spin"]["rate"]) is float
    assert study["body"]["dimensions"] == {"mass": 2.0, "a": 0.3, "b": 0.2, "c": 0.1}
    assert study["scan"]["rate"] == [1.0, 2.5]
    assert study["integration"]["horizon"] == 40.0 and type(study["integration"]["horizon"]) is float
    assert study["torque"] == {"profile": "sine", "vector": [0.0, 0.0, 1e-3], "period": 2.5, "duration": 0.0}


def test_a_mapping_study_with_numpy_values_and_tuples_resolves_to_plain_types():
    study = load_study({"body": {"moments": np.array([1.0, 2.0, 2.5])},
                        "perturbation": {"samples": np.int64(16), "amplitude": np.float32(0.5)},
                        "scan": {"axis": (1, 3)}})
    assert study["body"]["moments"] == [1.0, 2.0, 2.5]
    assert type(study["perturbation"]["samples"]) is int and study["perturbation"]["samples"] == 16
    assert study["scan"]["axis"] == [1, 3]
    json.dumps(study)


def test_the_input_mapping_is_not_modified():
    given = {"spin": {"axis": 3}, "scan": {"axis": [1, 2]}}
    before = copy.deepcopy(given)
    load_study(given)
    assert given == before


def test_overrides_replace_values_and_are_checked(tmp_path):
    path = write(tmp_path, "[perturbation]\nsamples = 8\n")
    study = load_study(path, overrides={"perturbation.samples": 64, "perturbation.seed": 3,
                                        "outputs.directory": "elsewhere"})
    assert study["perturbation"]["samples"] == 64 and study["perturbation"]["seed"] == 3
    assert study["outputs"]["directory"] == "elsewhere"
    with pytest.raises(StudyError) as err:
        load_study(path, overrides={"perturbation.samples": 0})
    assert err.value.field == "perturbation.samples"
    with pytest.raises(StudyError) as err:
        load_study(path, overrides={"perturbation.sample": 10})
    assert err.value.field == "perturbation.sample"


def test_shape_moments_fill_the_resolved_study_and_may_be_restated_only_if_equal():
    study = load_study({"body": {"shape": "cuboid", "dimensions": {"mass": 1, "a": 1, "b": 2, "c": 3}}})
    assert study["body"]["moments"] == pytest.approx(tumble.shapes.cuboid(1, 1, 2, 3).moments)
    assert load_study({"body": dict(study["body"])})["body"] == study["body"]


# ------------------------------------------------------------------------------------------------------
# Malformed studies: one StudyError each, naming the file and the exact field path

MALFORMED = [
    # TOML itself and the table structure
    ("spin = [1,\n", "<toml>"),
    ("[spin]\naxis = 1\naxis = 2\n", "<toml>"),
    ("sampels = 3\n", "sampels"),
    ("samples = 3\n", "samples"),
    ("[bodies]\nmoments = [1.0, 2.0, 3.0]\n", "bodies"),
    ("[perturbation]\nsampels = 10\n", "perturbation.sampels"),
    ("[spin]\namplitude = 0.1\n", "spin.amplitude"),
    ("body = 3\n", "body"),
    ("scan = [1, 2]\n", "scan"),
    ("[spin.rate]\nvalue = 1\n", "spin.rate"),
    ("[body]\ndimensions = 3\n", "body.dimensions"),
    ("title = 3\n", "title"),
    # body
    ("[body]\nmoments = 3\n", "body.moments"),
    ("[body]\nmoments = [1.0, 2.0]\n", "body.moments"),
    ("[body]\nmoments = [1.0, true, 3.0]\n", "body.moments[1]"),
    ("[body]\nmoments = [1.0, 2.0, '3']\n", "body.moments[2]"),
    ("[body]\nmoments = [1.0, 2.0, -3.0]\n", "body.moments[2]"),
    ("[body]\nmoments = [0, 2.0, 2.0]\n", "body.moments[0]"),
    ("[body]\nmoments = [1.0, nan, 2.0]\n", "body.moments[1]"),
    ("[body]\nmoments = [1.0, 1.0, 3.0]\n", "body.moments"),
    ("[body]\nshape = 'brick'\n", "body.shape"),
    ("[body]\nshape = 3\n", "body.shape"),
    ("[body]\nshape = 'cuboid'\ndimensions = {mass = 1, a = 1, b = 1, d = 1}\n", "body.dimensions.d"),
    ("[body]\nshape = 'cuboid'\ndimensions = {mass = 1, a = -1, b = 1, c = 1}\n", "body.dimensions.a"),
    ("[body]\nshape = 'cuboid'\ndimensions = {mass = 1}\n", "body.dimensions"),
    ("[body]\nshape = 'cuboid'\ndimensions = {mass = 1, a = 'big', b = 1, c = 1}\n", "body.dimensions.a"),
    ("[body]\nshape = 'rod'\ndimensions = {mass = 1, length = 1, about = 'middle'}\n", "body.dimensions.about"),
    ("[body]\nshape = 'rod'\ndimensions = {mass = 1, length = 1, about = 2}\n", "body.dimensions.about"),
    ("[body]\nshape = 'loaded_die'\ndimensions = {mass = 1, half_side = 1, load = 2}\n", "body.dimensions.load"),
    ("[body]\nshape = 'sphere'\ndimensions = {mass = 1, radius = inf}\n", "body.dimensions.radius"),
    ("[body]\ndimensions = {mass = 1}\n", "body.dimensions"),
    ("[body]\nshape = 'sphere'\nmoments = [1.0, 2.0, 3.0]\ndimensions = {mass = 1, radius = 1}\n",
     "body.moments"),
    # spin
    ("[spin]\naxis = 4\n", "spin.axis"),
    ("[spin]\naxis = 0\n", "spin.axis"),
    ("[spin]\naxis = 2.0\n", "spin.axis"),
    ("[spin]\naxis = true\n", "spin.axis"),
    ("[spin]\nrate = 0\n", "spin.rate"),
    ("[spin]\nrate = inf\n", "spin.rate"),
    ("[spin]\nrate = '1'\n", "spin.rate"),
    # perturbation
    ("[perturbation]\namplitude = -1e-3\n", "perturbation.amplitude"),
    ("[perturbation]\namplitude = 1.6\n", "perturbation.amplitude"),
    ("[perturbation]\namplitude = 1.6\ndistribution = 'filled_cone'\n", "perturbation.amplitude"),
    ("[perturbation]\nsamples = 0\n", "perturbation.samples"),
    ("[perturbation]\nsamples = 10.0\n", "perturbation.samples"),
    ("[perturbation]\nseed = -1\n", "perturbation.seed"),
    ("[perturbation]\nseed = 1979-05-27\n", "perturbation.seed"),
    ("[perturbation]\ndistribution = 'uniform'\n", "perturbation.distribution"),
    # integration
    ("[integration]\nmethod = 'rk5'\n", "integration.method"),
    ("[integration]\ndt = -0.1\n", "integration.dt"),
    ("[integration]\ndt = nan\n", "integration.dt"),
    ("[integration]\nflips = -1\n", "integration.flips"),
    ("[integration]\nflips = 1.5\n", "integration.flips"),
    ("[spin]\naxis = 3\n[integration]\nmethod = 'exact'\n[torque]\nprofile = 'constant'\nvector = [0, 0, 1]\n",
     "integration.method"),
    ("[integration]\nhorizon = -1.0\n", "integration.horizon", ">= 0"),
    ("[integration]\nhorizon = 'long'\n", "integration.horizon", "number"),
    ("[integration]\nhorizon = true\n", "integration.horizon", "number"),
    ("[integration]\nhorizon = inf\n", "integration.horizon", "finite"),
    ("[integration]\nhorizon = nan\n", "integration.horizon", "finite"),
    # torque
    ("[torque]\nprofile = 'spline'\n", "torque.profile"),
    ("[torque]\nprofile = 'lambda t: __import__(\"os\").system(\"true\")'\n", "torque.profile"),
    ("[torque]\nvector = [0, 0, 1]\n", "torque.vector"),
    ("[torque]\nprofile = 'constant'\nvector = [0, 1]\n", "torque.vector"),
    ("[torque]\nprofile = 'constant'\nvector = [0, 1, false]\n", "torque.vector[2]"),
    ("[torque]\nprofile = 'sine'\nvector = [0, 1, 0]\n", "torque.period"),
    ("[torque]\nprofile = 'ramp'\nvector = [0, 1, 0]\n", "torque.duration"),
    ("[torque]\nprofile = 'pulse'\nvector = [0, 1, 0]\nduration = -1\n", "torque.duration"),
    ("[torque]\nprofile = 'constant'\nvector = [0, 1, 0]\nperiod = 2\n", "torque.period"),
    # torque: about the spin axis only (linear theory), and then the spin axis is not scanned
    ("[torque]\nprofile = 'constant'\nvector = [0, 0, 1]\n", "torque.vector[2]", "linear theory"),
    ("[torque]\nprofile = 'constant'\nvector = [1e-3, 1e-3, 0]\n", "torque.vector[0]", "tumble.integrate"),
    ("[spin]\naxis = 3\n[torque]\nprofile = 'sine'\nvector = [0, -2, 1]\nperiod = 1\n", "torque.vector[1]",
     "must be 0"),
    ("[torque]\nprofile = 'constant'\n", "torque.vector[1]", "'none'"),
    ("[spin]\naxis = 1\n[torque]\nprofile = 'pulse'\nvector = [0, 0, 0]\nduration = 1\n", "torque.vector[0]",
     "non-zero"),
    ("[torque]\nprofile = 'constant'\nvector = [0, 1, 0]\n[scan]\naxis = [1, 2]\n", "scan.axis", "torque"),
    # scan
    ("[scan]\nspin = [1, 2]\n", "scan.spin"),
    ("[scan]\naxis = []\n", "scan.axis"),
    ("[scan]\naxis = 2\n", "scan.axis"),
    ("[scan]\naxis = [1, 5]\n", "scan.axis[1]"),
    ("[scan]\naxis = [1, 2, 1]\n", "scan.axis[2]"),
    ("[scan]\namplitude = [1e-3, 1e-3]\n", "scan.amplitude[1]"),
    ("[scan]\namplitude = [1e-3, 2.0]\n", "scan.amplitude[1]"),
    ("[scan]\nrate = [0, 1]\n", "scan.rate[0]"),
    ("[scan]\nmethod = ['rk4', 'euler']\n", "scan.method[1]"),
    ("[spin]\naxis = 1\n[scan]\nmethod = ['rk4', 'exact']\n[torque]\nprofile = 'constant'\nvector = [1, 0, 0]\n",
     "scan.method[1]"),
    ("[scan]\nmoments = [[1, 2, 3], [1, 1, 3]]\n", "scan.moments[1]"),
    ("[scan]\nmoments = [[1, 2, -3]]\n", "scan.moments[0][2]"),
    ("[scan]\nmoments = [[1, 2, 3], [1.0, 2.0, 3.0]]\n", "scan.moments[1]"),
    ("[scan]\nmoments = [1, 2, 3]\n", "scan.moments[0]"),
    ("[scan]\ntriangle = 1\n", "scan.triangle"),
    ("[scan]\ntriangle = 500\n", "scan.triangle"),
    ("[scan]\ntriangle = 20.0\n", "scan.triangle"),
    ("[scan]\ntriangle = [10, 20]\n", "scan.triangle"),
    ("[scan]\ntriangle = 10\nmoments = [[1, 2, 3]]\n", "scan.triangle"),
    ("[body]\nshape = 'sphere'\ndimensions = {mass = 1, radius = 1}\n[scan]\nmoments = [[1, 2, 3]]\n",
     "scan.moments"),
    # scan.body: each entry checked exactly like [body]
    ("[scan]\nbody = 3\n", "scan.body", "array"),
    ("[scan.body]\nshape = 'rod'\n", "scan.body", "array"),
    ("[scan]\nbody = []\n", "scan.body", "empty"),
    ("[scan]\nbody = [[1, 2, 3]]\n", "scan.body[0]", "table"),
    ("[scan]\nbody = [{label = 'nothing'}]\n", "scan.body[0]", "shape"),
    ("[scan]\nbody = [{moments = [1, 2, 3]}, {shap = 'rod'}]\n", "scan.body[1].shap", "did you mean 'shape'?"),
    ("[scan]\nbody = [{moments = [1, 2, 3], dimension = {}}]\n", "scan.body[0].dimension", "dimensions"),
    ("[scan]\nbody = [{shape = 'brick'}]\n", "scan.body[0].shape", "unknown value"),
    ("[scan]\nbody = [{shape = 'rod', dimensions = 3}]\n", "scan.body[0].dimensions", "table"),
    ("[scan]\nbody = [{dimensions = {mass = 1}}]\n", "scan.body[0].dimensions", "shape"),
    ("[scan]\nbody = [{shape = 'cuboid', dimensions = {mass = 1}}]\n", "scan.body[0].dimensions", "missing"),
    ("[scan]\nbody = [{moments = [1, 2, 3]}, {moments = [2, 3, 4]},\n"
     "        {shape = 'rod', dimensions = {mass = -1, length = 1}}]\n", "scan.body[2].dimensions.mass", "positive"),
    ("[scan]\nbody = [{shape = 'rod', dimensions = {mass = 1, lenght = 1}}]\n", "scan.body[0].dimensions.lenght",
     "length"),
    ("[scan]\nbody = [{moments = [1, 2, -3]}]\n", "scan.body[0].moments[2]", "> 0"),
    ("[scan]\nbody = [{moments = [1, 1, 3]}]\n", "scan.body[0].moments", "triangle"),
    ("[scan]\nbody = [{moments = [1, 2]}]\n", "scan.body[0].moments", "3 elements"),
    ("[scan]\nbody = [{shape = 'sphere', dimensions = {mass = 1, radius = 1}, moments = [1, 2, 3]}]\n",
     "scan.body[0].moments", "disagree"),
    ("[scan]\nbody = [{moments = [1, 2, 3], label = 7}]\n", "scan.body[0].label", "string"),
    ("[scan]\nbody = [{moments = [1, 2, 3], label = 'a'}, {moments = [2, 3, 4], label = 'b'},\n"
     "        {moments = [3, 4, 5], label = 'c'}, {moments = [1, 1.5, 1.7], label = 'b'}]\n",
     "scan.body[3].label", "distinct"),
    ("[scan]\nbody = [{shape = 'sphere', dimensions = {mass = 1, radius = 1}},\n"
     "        {shape = 'sphere', dimensions = {mass = 2, radius = 1}}]\n", "scan.body[1].label", "distinct"),
    ("[scan]\nbody = [{moments = [1, 2, 3]}, {moments = [2, 3, 4], label = 'body 0'}]\n", "scan.body[1].label",
     "distinct"),
    ("[scan]\nbody = [{moments = [1, 2, 3]}]\nmoments = [[1, 2, 3]]\n", "scan.body", "scan.moments"),
    ("[scan]\nbody = [{moments = [1, 2, 3]}]\ntriangle = 10\n", "scan.body", "scan.triangle"),
    ("[body]\nshape = 'sphere'\ndimensions = {mass = 1, radius = 1}\n[scan]\nbody = [{moments = [1, 2, 3]}]\n",
     "scan.body", "body.shape"),
    # outputs
    ("[outputs]\nfigures = 'summary'\n", "outputs.figures"),
    ("[outputs]\nfigures = ['summary', 'phase_portrait']\n", "outputs.figures[1]"),
    ("[outputs]\nfigures = ['summary', 'summary']\n", "outputs.figures[1]"),
    ("[outputs]\nformat = []\n", "outputs.format"),
    ("[outputs]\nformat = ['svg']\n", "outputs.format[0]"),
    ("[outputs]\narrays = ['omega']\n", "outputs.arrays[0]"),
    ("[outputs]\ndirectory = 3\n", "outputs.directory"),
    ("[outputs]\nfolder = 'x'\n", "outputs.folder"),
]


# (text, field) or (text, field, a word the problem must contain)
_CASES = [(case[0], case[1], case[2] if len(case) > 2 else "") for case in MALFORMED]


@pytest.mark.parametrize(("text", "field", "word"), _CASES, ids=[f"{i:03d}-{f}" for i, (_, f, _) in enumerate(_CASES)])
def test_a_malformed_study_names_its_file_and_field(tmp_path, text, field, word):
    path = write(tmp_path, text)
    with pytest.raises(StudyError) as err:
        load_study(path)
    message = str(err.value)
    assert message.startswith(f"{path}: {field}: "), message
    assert err.value.file == str(path) and err.value.field == field
    assert err.value.problem and "\n" not in err.value.problem
    assert word in err.value.problem, message


def test_there_are_many_malformed_cases():
    assert len(MALFORMED) >= 30


def test_toml_syntax_errors_give_the_line_and_column(tmp_path):
    path = write(tmp_path, "[spin]\naxis = 1\nrate = = 2\n")
    with pytest.raises(StudyError, match=r"line 3, column") as err:
        load_study(path)
    assert err.value.field == "<toml>"


def test_unknown_keys_suggest_the_closest_known_key(tmp_path):
    with pytest.raises(StudyError, match=r"perturbation\.sampels: unknown key .*did you mean 'samples'\?"):
        load_study(write(tmp_path, "[perturbation]\nsampels = 3\n"))
    with pytest.raises(StudyError, match=r"spin\.amplitude: .*did you mean perturbation\.amplitude\?"):
        load_study({"spin": {"amplitude": 0.1}})
    with pytest.raises(StudyError, match=r"body\.dimensions\.masss: .*did you mean 'mass'\?"):
        load_study({"body": {"shape": "sphere", "dimensions": {"masss": 1, "radius": 1}}})


def test_unknown_names_suggest_the_closest_allowed_name():
    with pytest.raises(StudyError, match=r"integration\.method: unknown value 'rk44'; did you mean 'rk4'\?"):
        load_study({"integration": {"method": "rk44"}})


def test_mapping_errors_name_the_mapping():
    with pytest.raises(StudyError) as err:
        load_study({"scan": {"amplitude": [1e-4, -1.0]}})
    assert str(err.value).startswith("<mapping>: scan.amplitude[1]: ")
    with pytest.raises(StudyError, match=r"^<mapping>: spin: keys must be strings"):
        load_study({"spin": {1: 2}})
    with pytest.raises(StudyError, match=r"^<mapping>: outputs\.figures\[0\]: "):
        load_study({"outputs": {"figures": [None]}})


@pytest.mark.parametrize("value", [True, 1.5, "1", None, [1]])
def test_integers_are_integers(value):
    with pytest.raises(StudyError) as err:
        load_study({"perturbation": {"samples": value}})
    assert err.value.field == "perturbation.samples"


def test_a_missing_file_is_a_study_error(tmp_path):
    missing = tmp_path / "nope.toml"
    with pytest.raises(StudyError) as err:
        load_study(missing)
    assert err.value.field == "<file>" and err.value.file == str(missing)
    with pytest.raises(StudyError, match="not a file"):
        load_study(tmp_path)


def test_a_file_that_is_not_utf8_is_a_study_error(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes("title = 'café'\n".encode("latin-1"))
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert err.value.field == "<toml>"


def test_anything_but_a_path_or_mapping_is_a_type_error():
    with pytest.raises(TypeError):
        load_study(42)


def test_study_error_is_a_value_error_that_pickles():
    err = StudyError("a.toml", "spin.axis", "must be 1, 2 or 3")
    assert isinstance(err, ValueError)
    assert str(err) == "a.toml: spin.axis: must be 1, 2 or 3"
    back = pickle.loads(pickle.dumps(err))
    assert (back.file, back.field, back.problem) == (err.file, err.field, err.problem)


def test_the_exact_method_is_fine_without_torque_and_auto_with_it():
    assert load_study({"integration": {"method": "exact"}})["integration"]["method"] == "exact"
    study = load_study({"spin": {"axis": 3}, "torque": {"profile": "pulse", "vector": [0, 0, 1], "duration": 0.5}})
    assert study["integration"]["method"] == "auto"


def test_gaussian_tilts_may_exceed_the_cone_limit():
    study = load_study({"perturbation": {"distribution": "gaussian", "amplitude": 2.0}})
    assert study["perturbation"]["amplitude"] == 2.0
    assert load_study({"perturbation": {"amplitude": math.nextafter(math.pi / 2, 0)}})


def test_a_flat_lamina_is_a_valid_body():
    assert load_study({"body": {"moments": [1.0, 2.0, 3.0]}})["body"]["moments"] == [1.0, 2.0, 3.0]
    assert load_study({"body": {"moments": [0.5, 0.5, 1.0]}})["body"]["moments"] == [0.5, 0.5, 1.0]


def test_the_horizon_defaults_to_the_planners_choice_and_takes_seconds():
    assert load_study({})["integration"]["horizon"] == 0.0
    study = load_study({"integration": {"horizon": 12}})
    assert study["integration"]["horizon"] == 12.0 and type(study["integration"]["horizon"]) is float


@pytest.mark.parametrize("axis", [1, 2, 3])
def test_a_torque_about_the_spin_axis_is_accepted_with_scans_of_other_keys(axis):
    vector = [0.0, 0.0, 0.0]
    vector[axis - 1] = -2e-3
    study = load_study({"spin": {"axis": axis}, "torque": {"profile": "constant", "vector": vector},
                        "scan": {"rate": [1, 2], "moments": [[1, 2, 3], [1, 1, 1.5]]}})
    assert study["torque"]["vector"] == vector
    assert study["scan"]["rate"] == [1.0, 2.0]


def test_scanning_the_spin_axis_is_fine_torque_free():
    assert load_study({"scan": {"axis": [1, 2, 3]}})["scan"]["axis"] == [1, 2, 3]


# ------------------------------------------------------------------------------------------------------
# Bodies from studies


def test_t_handle_with_default_dimensions():
    study = load_study({"body": {"shape": "t_handle"}})
    assert study["body"]["dimensions"] == {"mass": 0.05, "bar_length": 0.08, "bar_radius": 0.005,
                                           "stem_length": 0.04, "stem_radius": 0.005}
    body = config.resolve_body(study)
    assert body == tumble.shapes.t_handle()
    assert study["body"]["moments"] == body.moments.tolist()


def test_cuboid_with_dimensions(tmp_path):
    path = write(tmp_path, "[body]\nshape = 'cuboid'\n[body.dimensions]\nmass = 2\na = 0.3\nb = 0.2\nc = 0.1\n")
    body = config.resolve_body(load_study(path))
    np.testing.assert_array_equal(body.moments, tumble.shapes.cuboid(2.0, 0.3, 0.2, 0.1).moments)


def test_moments_without_a_shape_make_a_body():
    body = config.resolve_body(load_study({"body": {"moments": [2, 3, 4]}}))
    np.testing.assert_array_equal(body.moments, [2.0, 3.0, 4.0])


def test_rod_keeps_its_default_radius_out_of_the_study():
    study = load_study({"body": {"shape": "rod", "dimensions": {"mass": 1, "length": 2}}})
    assert study["body"]["dimensions"] == {"mass": 1.0, "length": 2.0, "about": "centre"}
    assert config.resolve_body(study) == tumble.shapes.rod(1.0, 2.0)


def test_bad_dimensions_name_the_argument():
    with pytest.raises(StudyError, match=r"body\.dimensions\.c: cuboid\(\): c must be a positive"):
        load_study({"body": {"shape": "cuboid", "dimensions": {"mass": 1, "a": 1, "b": 1, "c": 0}}})
    with pytest.raises(StudyError, match=r"body\.dimensions: missing b, c: cuboid\(\) takes mass, a, b, c"):
        load_study({"body": {"shape": "cuboid", "dimensions": {"mass": 1, "a": 1}}})


def test_scan_bodies_resolve_to_labels_shapes_filled_dimensions_and_moments(tmp_path):
    study = load_study(write(tmp_path, SCAN_BODY))
    rod = tumble.shapes.rod(1.0, 0.5, radius=0.01)
    cuboid = tumble.shapes.cuboid(2.0, 0.3, 0.2, 0.1)
    assert study["scan"]["body"] == [
        {"label": "rod", "shape": "rod", "dimensions": {"mass": 1.0, "length": 0.5, "about": "centre", "radius": 0.01},
         "moments": rod.moments.tolist()},
        {"label": "brick", "shape": "", "dimensions": {}, "moments": [1.0, 2.0, 3.0]},
        {"label": "cuboid", "shape": "cuboid", "dimensions": {"mass": 2.0, "a": 0.3, "b": 0.2, "c": 0.1},
         "moments": cuboid.moments.tolist()},
        {"label": "body 3", "shape": "", "dimensions": {}, "moments": [1.0, 1.5, 1.7]},
    ]
    assert list(study["scan"]["body"][0]) == ["label", "shape", "dimensions", "moments"]
    assert study["body"] == load_study({})["body"]  # the single-valued body is untouched
    assert load_study(study) == study
    assert load_study(json.loads(json.dumps(study))) == study


def test_scan_bodies_may_be_written_as_an_array_of_tables(tmp_path):
    text = ("[[scan.body]]\nshape = 'rod'\nlabel = 'stick'\n[scan.body.dimensions]\nmass = 1\nlength = 2\n"
            "[[scan.body]]\nmoments = [1, 2, 3]\n")
    study = load_study(write(tmp_path, text))
    assert [b["label"] for b in study["scan"]["body"]] == ["stick", "body 1"]
    assert study["scan"]["body"][0]["dimensions"] == {"mass": 1.0, "length": 2.0, "about": "centre"}


def test_scan_bodies_helper_gives_moments_and_labels_for_each_kind_of_scan(tmp_path):
    moments, labels = config.scan_bodies(load_study(write(tmp_path, SCAN_BODY)))
    assert moments.shape == (4, 3) and moments.dtype == np.float64
    assert labels == ["rod", "brick", "cuboid", "body 3"]
    np.testing.assert_array_equal(moments[0], tumble.shapes.rod(1.0, 0.5, radius=0.01).moments)
    np.testing.assert_array_equal(moments[1], [1.0, 2.0, 3.0])
    moments, labels = config.scan_bodies(load_study({"scan": {"moments": [[1, 2, 3], [1, 1.5, 1.7]]}}))
    np.testing.assert_array_equal(moments, [[1.0, 2.0, 3.0], [1.0, 1.5, 1.7]])
    assert labels == ["body 0", "body 1"]
    assert config.scan_bodies(load_study({"scan": {"triangle": 5}})) is None
    assert config.scan_bodies(load_study({"scan": {"axis": [1, 3]}})) is None
    assert config.scan_bodies(load_study({})) is None


# ------------------------------------------------------------------------------------------------------
# Bundled studies


@pytest.fixture
def studies_dir(tmp_path, monkeypatch):
    folder = tmp_path / "studies"
    folder.mkdir()
    shutil.copy(config.DEFAULTS_PATH, folder / "defaults.toml")
    (folder / "intermediate_axis.toml").write_text("title = 'The tennis-racket theorem'\n[spin]\naxis = 2\n")
    (folder / "plain.toml").write_text("[spin]\naxis = 3\n")
    (folder / "notes.md").write_text("not a study\n")
    monkeypatch.setattr(config, "STUDIES_DIR", folder)
    return folder


def test_bundled_studies_lists_names_and_titles(studies_dir):
    assert config.bundled_studies() == {"intermediate_axis": "The tennis-racket theorem", "plain": "plain"}


def test_a_bundled_study_loads_by_name(studies_dir):
    study = load_study("plain")
    assert study["spin"]["axis"] == 3 and study["title"] == "plain"
    assert load_study("intermediate_axis")["title"] == "The tennis-racket theorem"


def test_an_unknown_study_name_lists_the_bundled_ones(studies_dir):
    with pytest.raises(StudyError, match=r"^nope: <file>: .*bundled: intermediate_axis, plain"):
        load_study("nope")


def test_a_misspelt_study_name_suggests_the_close_bundled_one(studies_dir):
    with pytest.raises(StudyError, match=r"did you mean 'intermediate_axis'\? bundled: intermediate_axis, plain"):
        load_study("intermediat_axis")


def test_a_broken_bundled_study_is_reported_with_its_path(studies_dir):
    (studies_dir / "broken.toml").write_text("title = \n")
    with pytest.raises(StudyError, match="broken.toml: <toml>"):
        config.bundled_studies()


def test_no_bundled_folder_means_no_bundled_studies(tmp_path, monkeypatch):
    monkeypatch.setattr(config, "STUDIES_DIR", tmp_path / "missing")
    assert config.bundled_studies() == {}


# ------------------------------------------------------------------------------------------------------
# Safety


def test_the_config_layer_never_evaluates_or_unpickles():
    tree = ast.parse(open(config.__file__, encoding="utf-8").read())
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    assert not names & {"eval", "exec", "compile", "__import__"}
    imported = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))
                for a in n.names} | {(n.module or "").split(".")[0] for n in ast.walk(tree)
                                     if isinstance(n, ast.ImportFrom)}
    assert not imported & {"pickle", "marshal", "shelve", "dill", "importlib", "xarray", "matplotlib"}
