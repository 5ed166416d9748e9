#!/usr/bin/python3
"""structgp against scikit-learn's GaussianProcessRegressor, on the same split, in one run.

For each data set and each training size m, the same m training rows (evenly spaced over the
training part, so that they span the whole training period) are given to

  * scikit-learn: GaussianProcessRegressor with ConstantKernel * RBF (one length scale per
    input, ARD) + WhiteKernel, normalize_y=True, its own optimiser (L-BFGS-B on the log
    marginal likelihood, one start), all joints as one multi-output target;
  * structgp: pol+fri with type-II maximum likelihood, through the experiment program real_data
    (--models=pol+fri): the explicit feature map in weight space for 3 joints, the kernel
    form (PolFormulaKernel + friction) otherwise.

Both are timed as wall-clock time of the whole fit including the hyper-parameter optimisation
(structgp: as reported by real_data, without process start and file reading), and by the CPU
time of the process over fit and prediction (numpy's BLAS may use several threads; structgp
uses one). Test error:
nMSE per joint = MSE_j / Var(test tau_j), mean over joints.

Data sets: "sim3", a simulated three-joint KDL arm (experiment program sim_robot_data: 5,000
training and 2,000 following test rows), and "ur10", the real UR10 pick-and-place log
(train.csv.gz / test.csv.gz of --data-dir/ur10-picknplace).

Usage (from the source tree, after building real_data and sim_robot_data; Debian's python3
with python3-sklearn, see scripts/install-deps.sh):

    /usr/bin/python3 experiments/sklearn_compare.py --build-dir=/path/to/build [--sizes=1000,2000,5000]
        [--datasets=sim3,ur10] [--data-dir=../shared/data] [--out=docs/sklearn_comparison.csv]
"""

import argparse
import csv
import gzip
import os
import subprocess
import sys
import tempfile
import time

import numpy as np


def read_robot_csv(path):
    """Columns q1..qN, qd1..qdN, qdd1..qddN, tau1..tauN (and t if present)."""
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        reader = csv.reader(f)
        header = [h.strip() for h in next(reader)]
        rows = np.array([[float(v) for v in row] for row in reader if row])
    n = 0
    while "q%d" % (n + 1) in header:
        n += 1
    col = {name: i for i, name in enumerate(header)}
    x_cols = ["q%d" % j for j in range(1, n + 1)] + ["qd%d" % j for j in range(1, n + 1)] + [
        "qdd%d" % j for j in range(1, n + 1)]
    y_cols = ["tau%d" % j for j in range(1, n + 1)]
    X = rows[:, [col[c] for c in x_cols]]
    Y = rows[:, [col[c] for c in y_cols]]
    return X, Y, n


def write_robot_csv(path, X, Y, n):
    header = (["q%d" % j for j in range(1, n + 1)] + ["qd%d" % j for j in range(1, n + 1)] +
              ["qdd%d" % j for j in range(1, n + 1)] + ["tau%d" % j for j in range(1, n + 1)])
    np.savetxt(path, np.hstack([X, Y]), delimiter=",", header=",".join(header), comments="",
               fmt="%.17g")


def evenly_spaced(rows, count):
    """The same rows as EvenlySpaced in experiments/real_data.cc."""
    if count <= 0 or count >= rows:
        return np.arange(rows)
    return np.array([k * rows // count for k in range(count)])


def nmse(Y, P):
    return ((Y - P) ** 2).mean(axis=0) / Y.var(axis=0)


class _Budget(Exception):
    pass


def fit_sklearn(X, Y, X_test, Y_test, maxiter, max_seconds):
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel
    from scipy.optimize import minimize

    spread = X.std(axis=0)
    spread[spread <= 0] = 1.0
    kernel = (ConstantKernel(1.0, (1e-3, 1e3)) * RBF(length_scale=spread,
                                                       length_scale_bounds=(1e-3, 1e5)) +
              WhiteKernel(1e-2, (1e-8, 1e1)))
    status = {"evaluations": 0, "stopped": False}

    def optimizer(obj_func, initial_theta, bounds):
        # scikit-learn's default optimiser call (L-BFGS-B on -log p with its gradient), with an
        # optional iteration cap and a wall-clock budget: when the budget is spent, the best
        # point evaluated so far is returned (as structgp's --ml-seconds does).
        best = {"theta": initial_theta, "f": np.inf}
        start = time.perf_counter()

        def tracked(theta):
            f, g = obj_func(theta)
            status["evaluations"] += 1
            if f < best["f"]:
                best["theta"], best["f"] = np.array(theta), f
            if max_seconds > 0 and time.perf_counter() - start > max_seconds:
                status["stopped"] = True
                raise _Budget()
            return f, g

        options = {"maxiter": maxiter} if maxiter > 0 else {}
        try:
            res = minimize(tracked, initial_theta, method="L-BFGS-B", jac=True, bounds=bounds,
                           options=options)
            return res.x, res.fun
        except _Budget:
            return best["theta"], best["f"]

    gp = GaussianProcessRegressor(kernel=kernel, normalize_y=True, optimizer=optimizer,
                                  n_restarts_optimizer=0, random_state=0)
    start, cpu_start = time.perf_counter(), time.process_time()
    gp.fit(X, Y)
    fit_s = time.perf_counter() - start
    start = time.perf_counter()
    P = gp.predict(X_test)
    predict_s = time.perf_counter() - start
    cpu_s = time.process_time() - cpu_start
    if P.ndim == 1:
        P = P[:, None]
    note = "%d evaluations%s" % (status["evaluations"],
                                 ", stopped by the time budget" if status["stopped"] else "")
    return nmse(Y_test, P), fit_s, predict_s, str(gp.kernel_), cpu_s, note


def fit_structgp(real_data, train_path, test_path, name, m, work):
    out_csv = os.path.join(work, "structgp_%s_%d.csv" % (name, m))
    cmd = [real_data, "--train-file=" + train_path, "--test-file=" + test_path, "--name=" + name,
           "--models=pol+fri", "--kernel-rows=%d" % max(m, 10), "--csv=" + out_csv]
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if proc.returncode != 0:
        raise RuntimeError("%s failed (%d): %s" % (" ".join(cmd), proc.returncode, proc.stderr))
    with open(out_csv) as f:
        rows = list(csv.DictReader(f))
    row = rows[0]
    per_joint = np.array([float(v) for v in row["nmse_per_joint"].split(";")])
    note = ""
    for line in proc.stdout.splitlines():
        if line.startswith("pol+fri "):
            note = line.split("s  ", 1)[-1].strip() if "s  " in line else ""
    return (per_joint, float(row["fit_seconds"]), float(row["predict_seconds"]), note,
            float(row["cpu_seconds"]))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--build-dir", required=True,
                        help="CMake build directory holding experiments/real_data and "
                        "experiments/sim_robot_data")
    parser.add_argument("--data-dir", default=os.path.join(os.path.dirname(__file__), "..", "..",
                                                           "shared", "data"))
    parser.add_argument("--sizes", default="1000,2000,5000")
    parser.add_argument("--datasets", default="sim3,ur10")
    parser.add_argument("--sk-maxiter", type=int, default=0,
                        help="cap on scikit-learn's L-BFGS-B iterations (0: its default)")
    parser.add_argument("--sk-max-seconds", type=float, default=600.0,
                        help="wall-clock budget of scikit-learn's optimiser per fit; the best "
                        "point so far is used when it is spent (0: none)")
    parser.add_argument("--out", default="", help="CSV file for the results")
    args = parser.parse_args()

    real_data = os.path.join(args.build_dir, "experiments", "real_data")
    sim = os.path.join(args.build_dir, "experiments", "sim_robot_data")
    for exe in (real_data, sim):
        if not os.access(exe, os.X_OK):
            sys.exit("sklearn_compare: %s not found: build the targets real_data and "
                     "sim_robot_data first" % exe)
    sizes = [int(s) for s in args.sizes.split(",") if s]
    import sklearn
    print("scikit-learn %s, numpy %s" % (sklearn.__version__, np.__version__), flush=True)

    results = []
    with tempfile.TemporaryDirectory(prefix="sklearn_compare_") as work:
        for name in args.datasets.split(","):
            if name == "sim3":
                subprocess.run([sim, "--out-dir=" + work], check=True, stdout=subprocess.DEVNULL)
                train_file = os.path.join(work, "train.csv")
                test_file = os.path.join(work, "test.csv")
            elif name == "ur10":
                train_file = os.path.join(args.data_dir, "ur10-picknplace", "train.csv.gz")
                test_file = os.path.join(args.data_dir, "ur10-picknplace", "test.csv.gz")
                if not os.path.exists(train_file):
                    print("ur10: %s not found; skipped" % train_file)
                    continue
            else:
                sys.exit("sklearn_compare: unknown data set '%s' (sim3, ur10)" % name)
            X, Y, n = read_robot_csv(train_file)
            X_test, Y_test, _ = read_robot_csv(test_file)
            for m in sizes:
                idx = evenly_spaced(X.shape[0], m)
                sub = os.path.join(work, "%s_train_%d.csv" % (name, m))
                write_robot_csv(sub, X[idx], Y[idx], n)
                sg = fit_structgp(real_data, sub, test_file, name, len(idx), work)
                print("%s m=%d structgp pol+fri: mean nMSE %.4g, fit %.2f s (%s)" %
                      (name, len(idx), sg[0].mean(), sg[1], sg[3]), flush=True)
                sk = fit_sklearn(X[idx], Y[idx], X_test, Y_test, args.sk_maxiter,
                                 args.sk_max_seconds)
                print("%s m=%d scikit-learn: mean nMSE %.4g, fit %.2f s (%s), kernel %s" %
                      (name, len(idx), sk[0].mean(), sk[1], sk[5], sk[3]), flush=True)
                results.append((name, len(idx), sk, sg))

    print()
    print("| data | m | sklearn nMSE | sklearn fit s | sklearn CPU s | structgp nMSE | "
          "structgp fit s | structgp CPU s | speed ratio (wall) | ratio (CPU) | "
          "target (>= 20x, nMSE <=) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, m, sk, sg in results:
        ratio = sk[1] / sg[1] if sg[1] > 0 else float("nan")
        cpu_ratio = sk[4] / sg[4] if sg[4] > 0 else float("nan")
        met = ratio >= 20 and sg[0].mean() <= sk[0].mean()
        print("| %s | %d | %.4g | %.2f | %.1f | %.4g | %.2f | %.1f | %.1fx | %.1fx | %s |" %
              (name, m, sk[0].mean(), sk[1], sk[4], sg[0].mean(), sg[1], sg[4], ratio, cpu_ratio,
               ("met" if met else "not met") + ("; sklearn budget spent" if "budget" in sk[5]
                                               else "")))
    if args.out:
        tmp = args.out + ".tmp"
        with open(tmp, "w", newline="") as f:
            out = csv.writer(f)
            out.writerow(["dataset", "m", "sklearn_mean_nmse", "sklearn_fit_seconds",
                          "sklearn_predict_seconds", "sklearn_cpu_seconds", "structgp_mean_nmse",
                          "structgp_fit_seconds", "structgp_predict_seconds",
                          "structgp_cpu_seconds", "sklearn_nmse_per_joint",
                          "structgp_nmse_per_joint", "sklearn_note", "structgp_note",
                          "sklearn_kernel"])
            for name, m, sk, sg in results:
                out.writerow([name, m] + ["%.6g" % v for v in (sk[0].mean(), sk[1], sk[2], sk[4],
                                                               sg[0].mean(), sg[1], sg[2], sg[4])] +
                             [";".join("%.4g" % v for v in sk[0]),
                              ";".join("%.4g" % v for v in sg[0]), sk[5], sg[3], sk[3]])
        os.replace(tmp, args.out)
        print("wrote %s" % args.out)


if __name__ == "__main__":
    main()
