"""identify_chain: the module finds the same chain as `structgp identify` on the demo's slow log
(same options and seed), and its URDF serves Model('rbd+fri', urdf=...)."""

import json

import numpy as np
import pytest

import structgp
from conftest import run


def test_identify_chain_agrees_with_the_program_and_its_urdf_fits(cli, demo, tmp_path):
    train = structgp.read_robot_csv(str(demo / "train.csv"))
    test = structgp.read_robot_csv(str(demo / "test.csv"))
    found = structgp.identify_chain(train.X, train.Y, starts=3, threads=2)
    run(cli, "identify", "--data", demo / "train.csv", "--out", tmp_path / "cli.urdf",
        "--json", tmp_path / "cli.json", "--starts", 3, "--threads", 1, "--quiet")
    summary = json.loads((tmp_path / "cli.json").read_text())
    assert list(found["kinematics"]) == ["tilt", "theta1", "alpha2", "a2"]
    for name, value in found["kinematics"].items():
        assert value == pytest.approx(summary["kinematics"][name], abs=1e-12)
    assert found["urdf"] == (tmp_path / "cli.urdf").read_text()
    assert found["best_start"] + 1 == summary["best_start"]
    assert len(found["start_costs"]) == 3
    assert found["rounds"] == summary["rounds"] >= 1
    assert found["undetermined"] == summary["undetermined"]
    assert found["cost_change"].shape == (4,) and found["faster_change"].shape == (4,)
    # The demo's chain explains its log to the noise (1% of the largest torque, white).
    assert np.allclose(found["noise"], [j["noise"] for j in summary["joints"]], rtol=1e-12)
    assert np.all(found["residual_rms"] < 1.1 * found["noise"])

    path = tmp_path / "robot.urdf"
    path.write_text(found["urdf"])
    model = structgp.Model("rbd+fri", urdf=str(path)).fit(train.X, train.Y)
    mean = model.predict(test.X)
    nmse = np.mean((mean - test.Y) ** 2, axis=0) / np.var(test.Y, axis=0)
    assert np.all(nmse < 1e-2), nmse


def test_identify_chain_refuses_bad_input():
    X = np.zeros((10, 6))
    with pytest.raises(ValueError, match="expected 3 N = 6"):
        structgp.identify_chain(X[:, :5], np.ones((10, 2)))
    with pytest.raises(ValueError, match="threads"):
        structgp.identify_chain(X, np.ones((10, 2)), threads=0)


def test_identify_chain_takes_effects_and_their_time(demo):
    train = structgp.read_robot_csv(str(demo / "train.csv"))
    # The demo's hidden friction is a Coulomb step on joint 2, which +fri already holds: an
    # effect that reads the time is fitted beside it when t is given, refused without it.
    found = structgp.identify_chain(train.X, train.Y, train.t, effects="drift@2", starts=2,
                                    rounds=1, threads=2)
    assert found["rounds"] == 1
    assert np.all(found["residual_rms"] < 0.02 * found["torque_rms"])
    with pytest.raises(ValueError, match="uses the time"):
        structgp.identify_chain(train.X, train.Y, effects="drift@2", starts=2)
    with pytest.raises(ValueError, match="entries, expected one per row"):
        structgp.identify_chain(train.X, train.Y, train.t[:10], starts=2)
    with pytest.raises(ValueError, match="names joint 3"):
        structgp.identify_chain(train.X, train.Y, effects="offset@3", starts=2)
