"""The runner's one switch between scene kinds (free-body scenes, model scenes) and the typed options it passes down."""

import dataclasses
import pickle

import pytest

from tumble.pipeline import runner, schema
from tumble.pipeline.config import load_study

GYROSTAT = {"model": {"kind": "gyrostat", "rotor": [0.0, 0.5, 0.0]}, "perturbation": {"samples": 16},
            "integration": {"dt": 0.01}}


def test_the_scene_kind_is_chosen_once_from_the_study():
    free = runner.scene_job(load_study({"perturbation": {"samples": 16}}))
    model = runner.scene_job(load_study(GYROSTAT))
    assert free.scenes == runner.FreeScenes() and free.plan.scenes is free.scenes
    assert model.scenes == runner.ModelScenes("gyrostat")
    assert isinstance(free.options, runner.SceneOptions) and isinstance(model.options, runner.ModelSceneOptions)


def test_the_options_are_a_typed_record_read_as_keyword_arguments():
    resolved = load_study({"integration": {"dt": 0.02, "horizon": 0.0}, "torque": {"profile": "constant",
                                                                                  "vector": [0.0, 0.0, 1e-3]},
                           "spin": {"axis": 3}, "outputs": {"figures": ["summary"]}})
    options = runner.plan(resolved).options
    assert dict(options) == {"dt": 0.02, "flips": 3, "horizon": None, "distribution": "cone",
                             "torque": resolved["torque"], "curves": (), "device": "cpu"}
    assert options.dt == 0.02 and options["dt"] == 0.02 and "model" not in options
    with pytest.raises(dataclasses.FrozenInstanceError):
        options.dt = 1.0
    assert pickle.loads(pickle.dumps(options)) == options  # what a dask worker receives


def test_every_described_scene_option_reaches_the_records_that_take_it():
    described = {f.option for f in schema.FIELDS if f.option}
    assert described == set(runner.SceneOptions._names()) - {"torque", "curves"}
    assert set(runner.ModelSceneOptions._names()) <= described


def test_a_model_study_runs_through_its_scene_kind_as_a_free_study_through_its_own():
    for study in (GYROSTAT, {"perturbation": {"samples": 16}, "outputs": {"figures": ["summary"]}}):
        job = runner.scene_job(load_study(study))
        whole = runner.compute_scenes(job, [0])[0]
        parts = job.scenes.samples(runner._scene_plan(job, 0), 0, job.samples)
        again = runner._scene_record(job, runner._scene_plan(job, 0), [parts])
        assert whole["rate"] == again["rate"]
