"""save / Model.load round trip: the loaded model predicts, splits and reports exactly as the
saved one, and the structgp program reads the file the module wrote (and back)."""

import json

import numpy as np
import pytest

import structgp
from conftest import run


@pytest.fixture(scope="module")
def logs(demo):
    return (structgp.read_robot_csv(str(demo / "train.csv")),
            structgp.read_robot_csv(str(demo / "test.csv")))


@pytest.mark.parametrize("spec", ["pol+fri + coulomb@2", "motor+fri", "pol + drift@2"])
def test_a_saved_model_loads_back_exactly(logs, tmp_path, spec):
    train, test = logs
    model = structgp.Model(spec).fit(train.X, train.Y, train.t, hyper="fixed")
    path = tmp_path / "model.json"
    model.save(str(path))
    loaded = structgp.Model.load(str(path))
    assert loaded.spec == model.spec == structgp.parse_model(spec)
    assert loaded.fitted and loaded.summary is None
    assert loaded.uses_time == ("drift" in spec)
    t = test.t if loaded.uses_time else None
    for a, b in zip(model.predict(test.X, t, return_std=True),
                    loaded.predict(test.X, t, return_std=True)):
        np.testing.assert_array_equal(a, b)
    parts, loaded_parts = model.components(test.X, t), loaded.components(test.X, t)
    assert list(parts) == list(loaded_parts)
    for name in parts:
        np.testing.assert_array_equal(parts[name][0], loaded_parts[name][0])
        np.testing.assert_array_equal(parts[name][1], loaded_parts[name][1])
    assert model.coefficients().keys() == loaded.coefficients().keys()
    for name, (value, std) in model.coefficients().items():
        np.testing.assert_array_equal(value, loaded.coefficients()[name][0])
        np.testing.assert_array_equal(std, loaded.coefficients()[name][1])
    assert loaded.log_marginal_likelihood == model.log_marginal_likelihood
    assert loaded.model_file() == path.read_text() == model.model_file()


def test_the_program_reads_the_modules_file_and_the_module_reads_the_programs(cli, demo, logs,
                                                                             tmp_path):
    train, test = logs
    model = structgp.Model("pol+fri").fit(train.X, train.Y, hyper="fixed")
    path = tmp_path / "from_python.json"
    model.save(str(path))
    errors = tmp_path / "errors.json"
    run(cli, "evaluate", "--model", path, "--data", demo / "test.csv", "--json", errors)
    rms = json.loads(errors.read_text())["joints"]
    mean = model.predict(test.X)
    for j in range(2):
        assert rms[j]["rms"] == pytest.approx(np.sqrt(np.mean((mean[:, j] - test.Y[:, j]) ** 2)),
                                              rel=1e-12)
    # The program's fit --out - on stdout is a model file the module loads.
    text = run(cli, "fit", "--data", demo / "train.csv", "--model", "pol+fri", "--hyper", "fixed",
               "-q", "--out", "-").stdout
    (tmp_path / "stdout.json").write_text(text)
    np.testing.assert_array_equal(structgp.Model.load(str(tmp_path / "stdout.json")).predict(test.X),
                                  mean)


def test_coefficients_are_named_and_recover_the_hidden_friction(logs):
    train, _ = logs
    model = structgp.Model("pol", effects="coulomb@2").fit(train.X, train.Y)
    coefficients = model.coefficients()
    assert list(coefficients) == ["coulomb@2"]
    value, std = coefficients["coulomb@2"]
    # structgp demo hides 0.15 N m of Coulomb friction on joint 2.
    assert abs(value - 0.15) < 5 * std + 1e-3 and 0 < std < 0.01
    # The shared offset of +fri has one coefficient per joint torque.
    fri = structgp.Model("pol+fri").fit(train.X, train.Y, hyper="fixed").coefficients()
    assert set(fri) == {"viscous@1", "coulomb@1", "viscous@2", "coulomb@2", "offset"}
    assert fri["offset"][0].shape == (2,) and fri["offset"][1].shape == (2,)


def test_a_saved_lagk_model_loads_back_exactly(logs, tmp_path):
    """The Euler-Lagrange kernel GP through 150 inducing states: the rows and inducing states
    are stored, the posterior's factors in the posterior file, and the model loads to the same
    predictions bit for bit, also with the rows predicted on several threads and with the
    posterior computed from the rows instead."""
    train, test = logs
    X, Y = train.X[:600], train.Y[:600]
    model = structgp.Model("lagk+fri", inducing_states=150).fit(X, Y, None, hyper="fixed")
    path = tmp_path / "lagk.json"
    model.save(str(path))
    assert json.loads(path.read_text())["form"] == "euler_lagrange"
    # The posterior file next to it: load reads the posterior's factors from it.
    posterior = tmp_path / "lagk.json.posterior"
    assert posterior.exists()
    loaded = structgp.Model.load(str(path))
    assert loaded.posterior_file_read and loaded.posterior_file_note == ""
    computed = structgp.Model.load(str(path), posterior_file=False)
    assert not computed.posterior_file_read
    np.testing.assert_array_equal(computed.predict(test.X, None), loaded.predict(test.X, None))
    threaded = structgp.Model.load(str(path), threads=3)
    for a, b, c, d in zip(model.predict(test.X, None, return_std=True),
                          loaded.predict(test.X, None, return_std=True),
                          threaded.predict(test.X, None, return_std=True),
                          threaded.predict(test.X, None, return_std=True, threads=3)):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(a, c)
        np.testing.assert_array_equal(a, d)
    with pytest.raises(ValueError):
        structgp.Model.load(str(path), threads=0)
    with pytest.raises(ValueError):
        loaded.predict(test.X, None, threads=0)
    # As the CLI's --threads: at most 256 (more would start that many threads).
    with pytest.raises(ValueError, match="threads: expected 1 to 256, got 257"):
        loaded.predict(test.X, None, threads=257)
    with pytest.raises(ValueError, match="threads"):
        structgp.Model.load(str(path), threads=1000)
    with pytest.raises(ValueError, match="threads"):
        structgp.Model("pol", threads=257)
    # A damaged posterior file is not used, and says why; the predictions are the same.
    damaged = bytearray(posterior.read_bytes())
    damaged[-100] ^= 0x10
    posterior.write_bytes(bytes(damaged))
    reloaded = structgp.Model.load(str(path))
    assert not reloaded.posterior_file_read
    assert "CRC-32" in reloaded.posterior_file_note
    np.testing.assert_array_equal(reloaded.predict(test.X, None), loaded.predict(test.X, None))
    # Saved without it: none is left next to the model file.
    model.save(str(path), posterior_file=False)
    assert not posterior.exists()
