"""Bad input raises ValueError (or structgp.DataError, a ValueError, for files) with the
library's message: the same text the structgp program prints after 'error: '."""

import numpy as np
import pytest

import structgp
from conftest import run


@pytest.fixture(scope="module")
def train(demo):
    return structgp.read_robot_csv(str(demo / "train.csv"))


@pytest.fixture(scope="module")
def model(train):
    return structgp.Model("pol+fri").fit(train.X, train.Y, hyper="fixed")


def cli_message(result):
    """The message of 'structgp CMD: error: MESSAGE' on stderr."""
    line = next(l for l in result.stderr.splitlines() if ": error: " in l)
    return line.split(": error: ", 1)[1]


def test_a_wrong_number_of_columns_names_what_was_expected(model, train):
    with pytest.raises(ValueError) as e:
        model.predict(train.X[:, :5])
    assert str(e.value) == ("ModelInputs states: expected 6 columns (q, qd, qdd of each joint), "
                            "got 5")
    with pytest.raises(ValueError, match=r"^X: expected a 2-D array \(one row per sample\), "
                                         r"got shape 6$"):
        model.predict(train.X[0])
    with pytest.raises(ValueError, match=r"^X: expected an array of numbers, got str$"):
        model.predict("q1")


def test_nan_in_the_data_is_refused_naming_the_row(train):
    X = train.X.copy()
    X[7, 3] = np.nan
    with pytest.raises(ValueError) as e:
        structgp.Model("pol").fit(X, train.Y)
    assert "row 8" in str(e.value) or "row 7" in str(e.value), str(e.value)
    assert "NaN" in str(e.value) or "non-finite" in str(e.value), str(e.value)


def test_model_and_effect_texts_give_the_parsers_messages(cli, demo, tmp_path):
    for model, effects in [("pole", ""), ("pol+fri", "cogging@1:period=-1"),
                           ("pol", "coulomb@x"), ("pol", "bump@2")]:
        result = run(cli, "fit", "--data", demo / "train.csv", "--model", model,
                     *(["--effects", effects] if effects else []),
                     "--out", tmp_path / "m.json", "-q", expect=2)
        expected = cli_message(result).split(": ", 1)[1]  # without the flag name
        with pytest.raises(ValueError) as e:
            structgp.Model(model, effects=[effects] if effects else None)
        assert str(e.value) == expected
        with pytest.raises(ValueError) as e:
            structgp.Model(model + (" + " + effects if effects else ""))
        assert str(e.value) == expected
    with pytest.raises(ValueError, match="either as a spec text"):
        structgp.Model("pol", base="rbf")


def test_fit_options_and_an_unfitted_model(train):
    with pytest.raises(ValueError, match="^hyper: expected ml, cv or fixed, got 'map'$"):
        structgp.Model("pol").fit(train.X, train.Y, hyper="map")
    with pytest.raises(ValueError, match="not fitted"):
        structgp.Model("pol").predict(train.X)
    with pytest.raises(ValueError, match="torques"):
        structgp.Model("pol").fit(train.X, train.Y[:10])
    # A time effect needs t, in fit and in predict.
    with pytest.raises(ValueError, match="uses the time"):
        structgp.Model("pol", effects="drift@1").fit(train.X, train.Y)


def test_a_bad_data_file_is_a_data_error_with_the_programs_message(cli, tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("q1,qd1,qdd1,tau1\n0.1,0.2,0.3,0.4\n0.1,x,0.3,0.4\n")
    result = run(cli, "fit", "--data", bad, "--model", "pol", "--out", tmp_path / "m.json",
                 expect=2)
    with pytest.raises(structgp.DataError) as e:
        structgp.read_robot_csv(str(bad))
    assert str(e.value) == cli_message(result)
    assert str(e.value).startswith(f"{bad}:3:")
    assert isinstance(e.value, ValueError)
    with pytest.raises(structgp.DataError, match="expected 3 joints"):
        structgp.read_robot_csv(str(bad), joints=3)


def test_a_corrupted_model_file_is_refused_with_the_programs_message(cli, demo, tmp_path):
    text = (demo / "model_before.json").read_text()
    broken = tmp_path / "broken.json"
    broken.write_text(text.replace('"num_joints": 2', '"num_joints": 3'))
    result = run(cli, "evaluate", "--model", broken, "--data", demo / "test.csv", expect=2)
    with pytest.raises(structgp.DataError) as e:
        structgp.Model.load(str(broken))
    assert str(e.value) == cli_message(result)
    assert "checksum" in str(e.value)


def test_numerical_failures_are_structgp_errors():
    assert issubclass(structgp.Error, RuntimeError)
    assert not issubclass(structgp.Error, ValueError)
