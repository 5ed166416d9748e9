"""OnlineLearner replays a log sample by sample and ends where the batch fit of the same rows
with the same hyper-parameters is (batch vs online)."""

import numpy as np
import pytest

import structgp


def test_replaying_the_log_reaches_the_batch_posterior(demo):
    train = structgp.read_robot_csv(str(demo / "train.csv"))
    test = structgp.read_robot_csv(str(demo / "test.csv"))
    rows = slice(0, 1500)
    batch = structgp.Model("pol+fri").fit(train.X[rows], train.Y[rows])
    assert batch.form == "weight_space"
    online = structgp.OnlineLearner(batch, variance=True)
    prior_mean = online.predict(test.X[0])
    np.testing.assert_array_equal(prior_mean, np.zeros(2))  # learned from no data
    for x, y in zip(train.X[rows], train.Y[rows]):
        online.update(x, y)
    assert online.num_samples == 1500 and online.summary["updates"] == 1500
    mean, std = batch.predict(test.X[:200], return_std=True)
    for i in range(200):
        m, s = online.predict(test.X[i], return_std=True)
        # Rank-one updates against one batch factorisation: equal to rounding.
        np.testing.assert_allclose(m, mean[i], rtol=1e-7, atol=1e-9 * np.abs(mean).max())
        np.testing.assert_allclose(s, std[i], rtol=1e-6)


def test_bad_samples_are_refused_with_a_message(demo):
    train = structgp.read_robot_csv(str(demo / "train.csv"))
    model = structgp.Model("motor").fit(train.X, train.Y, hyper="fixed")
    online = structgp.OnlineLearner(model)
    with pytest.raises(ValueError, match="expected x of 6 and y of 2 entries, got 5 and 2"):
        online.update(train.X[0, :5], train.Y[0])
    x = train.X[0].copy()
    x[1] = np.inf
    with pytest.raises(ValueError, match="rejected_non_finite"):
        online.update(x, train.Y[0])
    with pytest.raises(ValueError, match="variance=True"):
        online.predict(train.X[0], return_std=True)
    with pytest.raises(ValueError, match="feature map"):
        structgp.OnlineLearner(structgp.Model("rbf").fit(train.X[:100], train.Y[:100],
                                                         hyper="fixed"))
