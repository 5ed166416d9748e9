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


def _model_on_a_chain_bent_by_a_ripple(cli, tmp_path):
    """The demo's logs with a cogging ripple on joint 2, the chain identify_chain finds from the
    slow log without being told of it, and rbd+fri fitted on that chain."""
    run(cli, "demo", "--effect", "cogging", "--joint", 2, "--out", tmp_path / "demo", "--quiet")
    train = structgp.read_robot_csv(str(tmp_path / "demo" / "train.csv"))
    test = structgp.read_robot_csv(str(tmp_path / "demo" / "test.csv"))
    found = structgp.identify_chain(train.X, train.Y, starts=4, rounds=1, threads=2)
    path = tmp_path / "robot.urdf"
    path.write_text(found["urdf"])
    model = structgp.Model("rbd+fri", urdf=str(path)).fit(train.X, train.Y, train.t)
    return train, test, found, model


def test_diagnose_loop_identifies_an_identified_chain_again(cli, tmp_path):
    # A cogging ripple on joint 2 the first identification is not told of: the loop names it and
    # identifies the chain again with it; with reidentify=False the chain stays.
    train, test, found, model = _model_on_a_chain_bent_by_a_ripple(cli, tmp_path)
    improved, loop = structgp.diagnose_loop(model, test.X, test.Y, test.t,
                                            train=(train.X, train.Y, train.t), rounds=1,
                                            threads=2)
    first = loop["rounds"][0]
    assert "cogging@2" in first["added"]
    identification = first["identification"]
    assert identification is not None and identification["seconds"] > 0
    assert len(identification["joints"]) == 2
    assert identification["cost"] < min(found["start_costs"])
    kept, loop_kept = structgp.diagnose_loop(model, test.X, test.Y, test.t,
                                             train=(train.X, train.Y, train.t), rounds=1,
                                             reidentify=False)
    assert loop_kept["rounds"][0]["identification"] is None
    assert loop_kept["rounds"][0]["added"] == first["added"]
    # The chain identified again predicts the fast log's joint 2 better.
    def rms(m):
        return np.sqrt(np.mean((m.predict(test.X, test.t) - test.Y)[:, 1] ** 2))
    assert rms(improved) < rms(kept)
    with pytest.raises(ValueError, match="threads"):
        structgp.diagnose_loop(model, test.X, test.Y, test.t, train=(train.X, train.Y, train.t),
                               threads=0)


def test_diagnose_identifies_an_identified_chain_again_on_both_logs(cli, tmp_path):
    # The first chain, bent by a cogging ripple it was not told of: the diagnosis identifies it
    # again on both logs with the ripple it names beside it, and says whether that chain
    # explains the fast log better; reidentify=False diagnoses the model's own chain.
    train, test, found, model = _model_on_a_chain_bent_by_a_ripple(cli, tmp_path)
    both = structgp.diagnose(model, test.X, test.Y, test.t, train=(train.X, train.Y, train.t),
                             threads=2)
    chain = json.loads(both.to_json())["chain"]
    assert chain is not None
    assert "cogging@2" in chain["effects"]
    assert len(chain["refit_rms_before"]) == len(chain["refit_rms_after"]) == 2
    assert chain["changed"] == bool(chain["joints"])
    for j in chain["joints"]:
        assert chain["refit_rms_after"][j - 1] < 0.97 * chain["refit_rms_before"][j - 1]
    assert list(chain["kinematics"]) == ["tilt", "theta1", "alpha2", "a2"]
    assert chain["urdf"].startswith("<?xml") and chain["seconds"] > 0
    assert any(s.effect == "cogging" and s.joint == 2 for s in both.suggestions)
    assert "chain: " in str(both)
    own = structgp.diagnose(model, test.X, test.Y, test.t, train=(train.X, train.Y, train.t),
                            reidentify=False)
    assert json.loads(own.to_json())["chain"] is None
    assert any(s.effect == "cogging" and s.joint == 2 for s in own.suggestions)
    with pytest.raises(ValueError, match="threads"):
        structgp.diagnose(model, test.X, test.Y, test.t, train=(train.X, train.Y, train.t),
                          threads=0)
