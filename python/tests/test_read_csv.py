"""read_robot_csv on files written here with the csv module (an independent writer): the numbers,
the joints, the times and the trajectories of a multi-trajectory file, gzip, currents."""

import csv
import gzip

import numpy as np

import structgp


def write(path, header, rows, opener=open):
    with opener(path, "wt", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)


def log(rng, m, t0):
    """m rows of a 2-joint log: t from t0 in steps of 0.01, random q, qd, qdd, tau."""
    values = rng.normal(size=(m, 8))
    t = t0 + 0.01 * np.arange(m)
    return np.column_stack([t, values])


def test_a_file_of_three_trajectories(tmp_path):
    rng = np.random.default_rng(11)
    parts = [log(rng, 40, 0.0), log(rng, 25, 0.0), log(rng, 30, 0.1)]
    rows = np.vstack(parts)
    header = ["t", "q1", "q2", "qd1", "qd2", "qdd1", "qdd2", "tau1", "tau2"]
    path = tmp_path / "three.csv"
    write(path, header, [[repr(v) for v in row] for row in rows])
    data = structgp.read_robot_csv(str(path))
    assert data.joints == 2 and data.size == len(data) == 95
    # t restarts at rows 40 (0.0 after 0.39) and 65 (0.1 after 0.24): three trajectories.
    assert data.segments == [0, 40, 65]
    np.testing.assert_array_equal(data.t, rows[:, 0])
    np.testing.assert_array_equal(data.X, rows[:, 1:7])
    np.testing.assert_array_equal(data.Y, rows[:, 7:9])
    assert data.target == "torque" and data.source == str(path)
    # The same file, gzip-compressed, columns in another order plus one the reader ignores.
    order = [8, 0, 3, 1, 7, 5, 2, 4, 6]
    gz = tmp_path / "three.csv.gz"
    write(gz, [header[k] for k in order] + ["note"],
          [[repr(row[k]) for k in order] + ["x"] for row in rows], opener=gzip.open)
    again = structgp.read_robot_csv(str(gz))
    assert again.segments == data.segments
    np.testing.assert_array_equal(again.X, data.X)
    np.testing.assert_array_equal(again.Y, data.Y)


def test_motor_currents_and_a_file_without_time(tmp_path):
    rng = np.random.default_rng(12)
    rows = rng.normal(size=(10, 4))
    path = tmp_path / "currents.csv"
    write(path, ["q1", "qd1", "qdd1", "cur1"], [[repr(v) for v in row] for row in rows])
    data = structgp.read_robot_csv(str(path))
    assert data.target == "current" and data.t is None and data.segments == [0]
    np.testing.assert_array_equal(data.Y[:, 0], rows[:, 3])


def test_write_robot_csv_reads_back_exactly(tmp_path):
    rng = np.random.default_rng(13)
    X, Y, t = rng.normal(size=(7, 6)), rng.normal(size=(7, 2)), np.arange(7) * 0.1
    path = tmp_path / "out.csv"
    structgp.write_robot_csv(str(path), X, Y, t)
    data = structgp.read_robot_csv(str(path))
    np.testing.assert_array_equal(data.X, X)
    np.testing.assert_array_equal(data.Y, Y)
    np.testing.assert_array_equal(data.t, t)
