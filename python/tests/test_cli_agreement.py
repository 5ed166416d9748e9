"""The module and the structgp program give the same results on the same data and model file:
predictions (to 1e-10), components, a fit of the same spec, and the diagnosis."""

import csv
import json

import numpy as np
import pytest

import structgp
from conftest import run


def read_columns(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, values = rows[0], np.array(rows[1:], dtype=float)
    return {name: values[:, k] for k, name in enumerate(header)}


@pytest.fixture(scope="module")
def cli_model(cli, demo, tmp_path_factory):
    """pol+fri + coulomb@2 fitted by `structgp fit` on the slow log."""
    path = tmp_path_factory.mktemp("cli") / "model.json"
    run(cli, "fit", "--data", demo / "train.csv", "--model", "pol+fri", "--effects", "coulomb@2",
        "--out", path, "--quiet")
    return path


def test_predictions_equal_the_programs_on_its_model_file(cli, demo, cli_model, tmp_path):
    pred = tmp_path / "pred.csv"
    run(cli, "predict", "--model", cli_model, "--data", demo / "test.csv", "--out", pred,
        "--components")
    columns = read_columns(pred)
    test = structgp.read_robot_csv(str(demo / "test.csv"))
    model = structgp.Model.load(str(cli_model))
    mean, std = model.predict(test.X, return_std=True)
    assert mean.shape == (1000, 2) and std.shape == (1000, 2)
    for j in range(2):
        np.testing.assert_allclose(mean[:, j], columns[f"tau{j + 1}_mean"], rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(std[:, j], columns[f"tau{j + 1}_std"], rtol=1e-10, atol=1e-10)
    parts = model.components(test.X)
    assert list(parts) == model.component_names
    for name, (part_mean, part_std) in parts.items():
        assert part_mean.shape == part_std.shape == (1000, 2)
        for j in range(2):
            np.testing.assert_allclose(part_mean[:, j], columns[f"tau{j + 1}_{name}"],
                                       rtol=1e-10, atol=1e-10)


def test_components_add_up_to_the_prediction(demo, cli_model):
    test = structgp.read_robot_csv(str(demo / "test.csv"))
    model = structgp.Model.load(str(cli_model))
    mean = model.predict(test.X)
    parts = model.components(test.X)
    assert {"inertial", "coriolis", "gravity", "friction"} <= set(parts)
    total = sum(part_mean for part_mean, _ in parts.values())
    np.testing.assert_allclose(total, mean, rtol=0, atol=1e-12 * np.abs(mean).max())
    # Each part is uncertain by less than the whole prior, and by something.
    for name, (_, part_std) in parts.items():
        assert np.all(part_std >= 0) and np.all(np.isfinite(part_std)), name


def test_a_fit_from_python_is_the_programs_fit(demo, cli_model):
    train = structgp.read_robot_csv(str(demo / "train.csv"))
    test = structgp.read_robot_csv(str(demo / "test.csv"))
    model = structgp.Model(base="pol", friction=True, effects=["coulomb@2"])
    assert model.fit(train.X, train.Y, train.t) is model
    reference = structgp.Model.load(str(cli_model))
    np.testing.assert_allclose(model.predict(test.X), reference.predict(test.X),
                               rtol=1e-10, atol=1e-10)
    assert model.log_marginal_likelihood == pytest.approx(reference.log_marginal_likelihood,
                                                          rel=1e-12)
    summary = model.summary
    assert summary.usable and summary.method == "ml" and summary.rows == 4000
    assert summary.termination in ("converged", "max_iterations", "line_search_failed")
    assert len(summary.starts) == 3
    assert summary.to_dict()["summary"]["termination"] == summary.termination


def test_a_per_joint_fit_from_python_is_the_programs(cli, demo, tmp_path):
    path = tmp_path / "per_joint.json"
    run(cli, "fit", "--data", demo / "train.csv", "--model", "pol+fri", "--per-joint",
        "--out", path, "--quiet")
    train = structgp.read_robot_csv(str(demo / "train.csv"))
    test = structgp.read_robot_csv(str(demo / "test.csv"))
    model = structgp.Model(base="pol", friction=True)
    model.fit(train.X, train.Y, train.t, per_joint=True)
    assert model.per_joint
    reference = structgp.Model.load(str(path))
    assert reference.per_joint
    np.testing.assert_allclose(model.predict(test.X), reference.predict(test.X),
                               rtol=1e-10, atol=1e-10)
    assert len(model.summary.to_dict()["summary"]["joints"]) == 2
    shared = structgp.Model(base="pol", friction=True).fit(train.X, train.Y, train.t)
    assert not shared.per_joint


def test_calibrated_bands_from_python_are_the_programs(cli, demo, tmp_path):
    """pol without the friction the log holds: joint 2's held-out band is too narrow, and the
    fit scales its latent variance (the default); --no-calibrate-bands keeps the posterior's."""
    calibrated, plain = tmp_path / "calibrated.json", tmp_path / "plain.json"
    run(cli, "fit", "--data", demo / "train.csv", "--model", "pol", "--out", calibrated, "--quiet")
    run(cli, "fit", "--data", demo / "train.csv", "--model", "pol", "--no-calibrate-bands",
        "--out", plain, "--quiet")
    train = structgp.read_robot_csv(str(demo / "train.csv"))
    test = structgp.read_robot_csv(str(demo / "test.csv"))
    model = structgp.Model(base="pol").fit(train.X, train.Y, train.t)
    unscaled = structgp.Model(base="pol").fit(train.X, train.Y, train.t, calibrate_bands=False)
    kappa = model.latent_variance_scale
    assert kappa[1] > 1.0
    np.testing.assert_array_equal(unscaled.latent_variance_scale, np.ones(2))
    np.testing.assert_allclose(kappa, model.summary.to_dict()["summary"]["check"]
                               ["latent_variance_scale"], rtol=0, atol=0)
    for fitted, path in ((model, calibrated), (unscaled, plain)):
        reference = structgp.Model.load(str(path))
        np.testing.assert_array_equal(reference.latent_variance_scale,
                                      fitted.latent_variance_scale)
        mean, std = fitted.predict(test.X, return_std=True)
        ref_mean, ref_std = reference.predict(test.X, return_std=True)
        np.testing.assert_allclose(mean, ref_mean, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(std, ref_std, rtol=1e-10, atol=1e-10)
    mean, std = model.predict(test.X, return_std=True)
    plain_mean, plain_std = unscaled.predict(test.X, return_std=True)
    np.testing.assert_array_equal(mean, plain_mean)
    np.testing.assert_allclose(std, plain_std * np.sqrt(kappa), rtol=1e-12)


def test_the_diagnosis_has_the_content_of_findings_json(cli, demo, tmp_path):
    findings = tmp_path / "findings.json"
    run(cli, "diagnose", "--model", demo / "model_before.json", "--data", demo / "train.csv",
        "--json", findings)
    expected = json.loads(findings.read_text())
    train = structgp.read_robot_csv(str(demo / "train.csv"))
    model = structgp.Model.load(str(demo / "model_before.json"))
    report = tmp_path / "report.html"
    diagnosis = structgp.diagnose(model, train.X, train.Y, train.t, report=str(report))
    assert diagnosis.to_dict() == expected
    assert json.loads(diagnosis.to_json()) == expected
    assert "<html" in report.read_text()
    # The objects carry the same numbers.
    assert [s.spec for s in diagnosis.suggestions] == [s["spec"] for s in expected["suggestions"]]
    first = diagnosis.suggestions[0]
    assert (first.effect, first.joint) == ("coulomb", 2)
    assert first.score == expected["suggestions"][0]["score"]
    assert [(a.spec, a.scope, a.score) for a in first.alternatives] == \
        [(a["spec"], a["scope"], a["score"]) for a in expected["suggestions"][0]["alternatives"]]
    assert [f.rms for f in diagnosis.joints] == [f["rms"] for f in expected["joints"]]
    assert (diagnosis.verdict, diagnosis.verdict_message) == \
        (expected["coverage"]["verdict"], expected["coverage"]["message"])
    assert diagnosis.unexplained_joints == expected["coverage"]["unexplained_joints"]
    assert diagnosis.holding_torque_message == expected["holding_torque"]["message"]
    assert diagnosis.holding_torque_joints == \
        [h["joint"] for h in expected["holding_torque"]["joints"]]
    assert [f.residual_rms_with_suggestions for f in diagnosis.joints] == \
        [f["residual_rms_with_suggestions"] for f in expected["joints"]]
    # The refused candidates too, with the bar each failed.
    assert [(r.candidate.spec, r.bar, r.reason) for r in diagnosis.refused] == \
        [(r["spec"], r["refused_by"], r["reason"]) for r in expected["refused"]]
    assert "missing Coulomb friction" in str(diagnosis)
    assert structgp.parse_model(diagnosis.suggested_model) == "pol + coulomb@2:width=0.01"


def test_the_diagnosis_with_prewhitening_is_the_programs(cli, demo, tmp_path):
    findings = tmp_path / "findings.json"
    run(cli, "diagnose", "--model", demo / "model_before.json", "--data", demo / "train.csv",
        "--json", findings, "--autocorrelation", "prewhitening")
    expected = json.loads(findings.read_text())
    train = structgp.read_robot_csv(str(demo / "train.csv"))
    model = structgp.Model.load(str(demo / "model_before.json"))
    diagnosis = structgp.diagnose(model, train.X, train.Y, train.t,
                                  autocorrelation="prewhitening")
    assert diagnosis.to_dict() == expected
    assert diagnosis.suggestions and diagnosis.suggestions[0].spec.startswith("coulomb@2")
    with pytest.raises(ValueError, match="autocorrelation"):
        structgp.diagnose(model, train.X, train.Y, train.t, autocorrelation="white")


def test_the_diagnosis_loop_is_the_programs(cli, demo, tmp_path):
    """diagnose_loop and `structgp diagnose --rounds`: the same rounds, and the same improved
    model (its predictions equal to the digit)."""
    loop_json, improved = tmp_path / "loop.json", tmp_path / "improved.json"
    run(cli, "diagnose", "--model", demo / "model_before.json", "--data", demo / "test.csv",
        "--train", demo / "train.csv", "--rounds", 3, "--out", improved, "--json", loop_json)
    expected = json.loads(loop_json.read_text())
    train = structgp.read_robot_csv(str(demo / "train.csv"))
    log = structgp.read_robot_csv(str(demo / "test.csv"))
    model = structgp.Model.load(str(demo / "model_before.json"))
    better, loop = structgp.diagnose_loop(model, log.X, log.Y, log.t,
                                          train=(train.X, train.Y, train.t), rounds=3)
    assert loop["termination"] == expected["termination"]
    assert [r["added"] for r in loop["rounds"]] == [r["added"] for r in expected["rounds"]]
    assert loop["rounds"][0]["added"] == "coulomb@2"
    assert loop["model"] == expected["model"]
    program = structgp.Model.load(str(improved))
    assert np.array_equal(better.predict(log.X), program.predict(log.X))
    assert not np.array_equal(better.predict(log.X), model.predict(log.X))
    with pytest.raises(ValueError):
        structgp.diagnose_loop(model, log.X, log.Y, log.t, train=(train.X,), rounds=3)


def test_a_lagk_fit_from_another_model_is_the_programs(cli, demo, tmp_path):
    """start_from (structgp fit --start-from): the evidence search of a lagk model with an
    effect added starts from another lagk model, at its sigma; the module and the program give
    the same model."""
    with open(demo / "train.csv", newline="") as f:
        rows = list(csv.reader(f))[:301]
    small = tmp_path / "small.csv"
    with open(small, "w", newline="") as f:
        csv.writer(f).writerows(rows)
    base_path, cli_path = tmp_path / "base.json", tmp_path / "from.json"
    run(cli, "fit", "--data", small, "--model", "lagk+fri", "--hyper", "fixed", "--out", base_path,
        "--quiet")
    run(cli, "fit", "--data", small, "--model", "lagk+fri", "--effects", "offset@1",
        "--start-from", base_path, "--out", cli_path, "--quiet")
    data = structgp.read_robot_csv(str(small))
    base = structgp.Model.load(str(base_path))
    model = structgp.Model("lagk+fri + offset@1").fit(data.X, data.Y, data.t, start_from=base)
    assert "from the given hyper-parameters" in model.summary.method_description
    saved = json.loads(cli_path.read_text())
    assert saved["hyperparameters"]["shape"][0] == json.loads(base_path.read_text())["hyperparameters"]["shape"][0]
    test = structgp.read_robot_csv(str(demo / "test.csv"))
    np.testing.assert_allclose(model.predict(test.X), structgp.Model.load(str(cli_path)).predict(test.X),
                               rtol=1e-10, atol=1e-10)
    with pytest.raises(ValueError, match="start_from"):
        structgp.Model("pol+fri").fit(data.X, data.Y, data.t, start_from=base)


def test_the_noisy_band_covers_what_evaluate_says(cli, demo, cli_model, tmp_path):
    errors = tmp_path / "errors.json"
    run(cli, "evaluate", "--model", cli_model, "--data", demo / "test.csv", "--json", errors)
    reported = json.loads(errors.read_text())
    test = structgp.read_robot_csv(str(demo / "test.csv"))
    model = structgp.Model.load(str(cli_model))
    assert model.noise_std.shape == (2,) and (model.noise_std > 0).all()
    mean, std = model.predict(test.X, return_std=True)
    band = 2.0 * np.sqrt(std**2 + model.noise_std**2)
    inside = (np.abs(test.Y - mean) <= band).mean(axis=0)
    for j in range(2):
        assert reported["joints"][j]["coverage"] == pytest.approx(inside[j], abs=1e-12)
