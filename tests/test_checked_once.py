"""Device, torque step, cost and method are checked where a run enters (a public call, a scene's planner) and
trusted below it (issue 40, item 5): a planned scene's samples run through the engine's unchecked door
(tumble.engine.ensemble.run_planned), and every public call still refuses a bad argument with the same message."""

from types import SimpleNamespace

import numpy as np
import pytest

import tumble
from tumble import registry
from tumble.physics import models as physics_models
from tumble.engine import cost, ensemble, integration, model_ensemble
from tumble.measure import model_scenes, planning, running, scans
from tumble.measure import scene as scene_module
from tumble.pipeline import config, runner
from tumble.pipeline.config import StudyError

BODY = (1.0, 2.0, 3.0)
SHORT_PULSE = {"profile": "pulse", "vector": (0.0, 0.0, 1e-3), "duration": 1e-4}


def _refused(*args, **kwargs):
    raise AssertionError("checked again below the boundary")


@pytest.mark.parametrize("axis, method, torque", [(2, "rk4", None), (1, "rk4", None),
                                                  (3, "rk4", {"profile": "sine", "vector": (0, 0, 1e-3),
                                                              "period": 50.0})],
                         ids=["exponential", "periodic", "torqued"])
def test_a_planned_scene_runs_without_checking_its_device_torque_cost_or_method_again(monkeypatch, axis, method,
                                                                                       torque):
    scene = planning.scene_plan(BODY, axis, samples=16, method=method, torque=torque)
    reference = running.scene_samples(scene, 0, 16)
    monkeypatch.setattr(ensemble, "resolve_device", _refused)
    monkeypatch.setattr(ensemble, "choose_method", _refused)
    monkeypatch.setattr(ensemble, "check_on_device", _refused)
    monkeypatch.setattr(registry, "profile_step_problem", _refused)
    monkeypatch.setattr(cost, "check", _refused)
    part = running.scene_samples(scene, 0, 16)
    assert np.array_equal(part["rate"], reference["rate"]) and np.array_equal(part["code"], reference["code"])


def test_measure_refuses_a_pulse_its_planned_step_cannot_resolve_before_any_kernel_runs(monkeypatch):
    monkeypatch.setattr(running, "run_planned", _refused)
    with pytest.raises(planning.TorqueStepError) as info:
        tumble.measure(BODY, 3, samples=8, torque=SHORT_PULSE)
    assert str(info.value).startswith("torque.duration: 0.0001 s spans") and info.value.key == "duration"
    with pytest.raises(ValueError, match="torque.duration: 0.0001 s spans"):
        tumble.scan(BODY, 3, samples=8, torque=SHORT_PULSE)


def test_propagate_refuses_a_pulse_shorter_than_its_step_as_integrate_does():
    w = np.array([[0.0, 0.0, 1.0]])
    for call in (tumble.propagate, tumble.integrate):
        with pytest.raises(ValueError, match=r"torque duration: 0.05 s spans 0.5 step\(s\) of 0.1 s"):
            call(BODY, w, 1.0, 0.1, torque={"profile": "pulse", "vector": (0, 0, 1), "duration": 0.05})


def test_integrate_checks_its_run_once_and_the_engine_trusts_it(monkeypatch):
    w = np.array([[0.1, 1.0, 0.0]])
    reference = tumble.integrate(BODY, w, 1.0, 0.01, method="rk4", save_every=10)
    checks = []
    real_refuse = cost.refuse
    monkeypatch.setattr(cost, "refuse", lambda *a, **k: checks.append(a[1]) or real_refuse(*a, **k))
    monkeypatch.setattr(ensemble, "resolve_device", _refused)
    monkeypatch.setattr(ensemble, "choose_method", _refused)
    again = tumble.integrate(BODY, w, 1.0, 0.01, method="rk4", save_every=10)
    assert np.array_equal(again.omega.values, reference.omega.values)
    assert len(checks) == 1, checks  # integrate's own bound, not the engine's again
    assert integration.run_planned is ensemble.run_planned


@pytest.mark.parametrize("call", [tumble.propagate, tumble.integrate], ids=["propagate", "integrate"])
def test_an_absurd_step_count_is_refused_by_the_cost_bound_before_the_torque_step_is_checked(call):
    with pytest.raises(cost.TooLarge, match="t_end / dt = inf steps"):
        call(BODY, np.array([[0.0, 1.0, 0.0]]), 1e10, 1e-300, torque=SHORT_PULSE)


def test_a_study_names_its_torque_field_and_the_step_planned_for_the_scene_when_the_step_cannot_resolve_a_pulse():
    """The planner refuses the pulse (planning.TorqueStepError); the study says it in its own fields: the torque's
    ``torque.duration`` and the step's ``integration.dt``, not the planner's ``dt``."""
    study = {"outputs": {"figures": []}, "spin": {"axis": 3}, "perturbation": {"samples": 8},
             "torque": {"profile": "pulse", "vector": [0.0, 0.0, 1e-3], "duration": 1e-4}}
    with pytest.raises(StudyError) as info:
        tumble.run_study(study)
    err = info.value
    assert err.field == "torque.duration", str(err)
    assert err.problem.startswith("0.0001 s spans") and "set integration.dt <= " in err.problem, str(err)
    assert err.problem.endswith("(the step planned for scene 0)"), str(err)
    assert str(err).startswith("<mapping>: torque.duration: 0.0001 s spans"), str(err)


def _counted(monkeypatch, module):
    """Count the calls of ``module.resolve_device`` (a list of the devices asked)."""
    calls, real = [], module.resolve_device
    monkeypatch.setattr(module, "resolve_device", lambda device: calls.append(device) or real(device))
    return calls


def test_a_study_resolves_its_device_once_where_it_enters_and_its_scenes_trust_it(monkeypatch):
    calls = _counted(monkeypatch, runner)
    for module in (scene_module, scans, ensemble):
        monkeypatch.setattr(module, "resolve_device", _refused)
    ds = tumble.run_study({"outputs": {"figures": []}, "perturbation": {"samples": 8},
                           "scan": {"axis": [1, 2], "method": ["rk4", "auto"]}})
    assert calls == ["cpu"] and ds.rate.sizes["axis"] == ds.rate.sizes["method"] == 2


def test_scan_resolves_its_device_once_for_all_its_scenes(monkeypatch):
    calls = _counted(monkeypatch, scans)
    monkeypatch.setattr(scene_module, "resolve_device", _refused)
    monkeypatch.setattr(ensemble, "resolve_device", _refused)
    ds = tumble.scan(BODY, [1, 2], samples=8, method=["rk4", "auto"])
    assert calls == ["cpu"] and ds.rate.sizes["axis"] == ds.rate.sizes["method"] == 2
    with pytest.raises(ValueError, match="device must be one of"):
        tumble.scan(BODY, [1, 2], samples=8, device="gpu")
    with pytest.raises(ValueError, match="device must be one of"):
        scans.scan_scene(scans.scan_layout(BODY, [1, 2]), 0, samples=8, device="gpu")


def _decay(t, y, p, dydt):
    dydt[0] = -p[0] * y[0]


@pytest.mark.parametrize("system, kwargs", [
    (BODY, {"axis": 2}),
    (physics_models.Gyrostat(BODY, (0.0, 0.5, 0.0)), {"axis": 2}),
    (tumble.System(_decay, state=("x",), parameters={"k": -0.5}, name="growth"), {"state": [0.0]}),
], ids=["body", "model", "system"])
def test_measure_resolves_its_device_once_at_its_door_and_the_scene_trusts_it(monkeypatch, system, kwargs):
    """The device is resolved once per call, where the public call enters: measure of a body, a built-in model and a
    System; the planners (free body, model, System) and the runs below them (run_system) do not ask again."""
    from tumble.engine import system_runs
    from tumble.measure import system_scenes

    for module in (planning, model_scenes, system_scenes, system_runs):
        assert not hasattr(module, "resolve_device"), module.__name__
    calls = _counted(monkeypatch, scene_module)
    monkeypatch.setattr(ensemble, "resolve_device", _refused)
    monkeypatch.setattr(model_ensemble, "resolve_device", _refused)
    tumble.measure(system, samples=16, **kwargs)
    assert calls == ["cpu"]


def test_a_studys_estimate_asks_its_scene_kind_whether_every_scene_steps_and_grows():
    free = config.load_study({"spin": {"axis": 2}, "integration": {"method": "auto"}})
    top = config.load_study("sleeping_top")
    assert runner._scene_kind(free).always_steps is False and runner._scene_kind(top).always_steps is True
    assert runner._scene_kind(free).only_exponential(free) is True
    assert runner._scene_kind(top).only_exponential(top) is False
    assert runner.study_cost(free).sample_steps == 0.0  # torque-free "auto": the closed form
    top["integration"]["method"] = "auto"
    assert runner.study_cost(top).sample_steps > 0.0  # a model steps (rk4 for "auto")


def test_a_model_ensemble_past_the_cost_bound_is_refused_before_anything_runs(monkeypatch):
    monkeypatch.setattr(model_ensemble, "run_model", _refused)
    top = physics_models.FreeBody(BODY)
    with pytest.raises(cost.TooLarge, match=r"^y0 \(1,000 states\) over t_end / dt = 1e\+13 steps: 1e\+16 "
                                            r"sample-steps is more than"):
        model_ensemble.run_model_ensemble(top, np.ones((1000, 3)), 1e10, 1e-3, axis=3)
    with pytest.raises(cost.TooLarge, match=r"^y0 \(1,000 states\) over t_end / dt = 1e\+08 steps: needs ~") as info:
        model_ensemble.run_model_ensemble(top, np.ones((1000, 3)), 1e5, 1e-3, axis=3, save_every=1)  # 2.4 TB of states
    assert info.value.bound == "memory"


@pytest.mark.parametrize("kind, axis, parameters", [("gyrostat", 1, {"rotor": 0.5}), ("heavy_top", 3, {"mgl": 0.1})],
                         ids=["gyrostat", "heavy_top"])
def test_a_planned_model_scene_runs_without_checking_its_device_method_or_cost_again(monkeypatch, kind, axis,
                                                                                     parameters):
    model = model_scenes.model_of(kind, BODY, axis, parameters)
    scene = model_scenes.scene_plan(model, axis, 2.0, samples=16)
    reference = model_scenes.scene_samples(scene, 0, 16)
    monkeypatch.setattr(model_ensemble, "resolve_device", _refused)
    monkeypatch.setattr(model_ensemble, "check_model_method", _refused)
    monkeypatch.setattr(model_ensemble, "cost", SimpleNamespace(refuse=_refused, run_cost=_refused))  # its bound
    part = model_scenes.scene_samples(scene, 0, 16)
    assert np.array_equal(part["rate"], reference["rate"]) and np.array_equal(part["code"], reference["code"])


def test_a_model_scene_refuses_a_method_its_model_cannot_step_when_planned():
    damper = model_scenes.model_of("damper", BODY, 1, {"damper_inertia": 0.1, "damping": 0.05})
    with pytest.raises(ValueError, match="method must be one of rk4, rk8 for a damper model, got 'splitting2'"):
        model_scenes.scene_plan(damper, 1, 1.0, samples=16, method="splitting2")
