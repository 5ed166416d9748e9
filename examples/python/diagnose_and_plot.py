#!/usr/bin/env python3
"""Fit, diagnose, add the suggested effect, refit, and plot before/after (matplotlib, Agg).

The data are the demo's (`structgp demo`): a two-link arm simulated with Orocos KDL whose joint
2 has a Coulomb friction of 0.15 N m that the starting model `pol` does not know about; a slow
log to fit on and the same path 2.5x faster, unseen, to test on. Or your own logs:

    PYTHONPATH=build/python python3 examples/python/diagnose_and_plot.py --out figure.png
    PYTHONPATH=build/python python3 examples/python/diagnose_and_plot.py \
        --train train.csv --test test.csv --out figure.png
"""

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import structgp  # noqa: E402


def rms(a, b):
    return np.sqrt(np.mean((a - b) ** 2, axis=0))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--train", help="training log (CSV); default: the demo's simulated log")
    parser.add_argument("--test", help="test log (CSV); default: the demo's fast log")
    parser.add_argument("--model", default="pol", help="starting model (default: pol)")
    parser.add_argument("--out", default="diagnose_and_plot.png", help="figure to write (PNG)")
    args = parser.parse_args()

    if args.train:
        train = structgp.read_robot_csv(args.train)
        test = structgp.read_robot_csv(args.test or args.train)
    else:
        train, test = structgp.simulate_hidden_effect(robot="two-link", effect="coulomb", joint=2)

    before = structgp.Model(args.model).fit(train.X, train.Y, train.t)
    diagnosis = structgp.diagnose(before, train.X, train.Y, train.t)
    print(diagnosis)
    after = structgp.Model(diagnosis.suggested_model).fit(train.X, train.Y, train.t)
    for name, (value, std) in after.coefficients().items():
        print(f"fitted {name}: {np.round(value, 4)} +- {np.round(std, 4)}")

    t_test = test.t if after.uses_time or before.uses_time else None
    mean_before = before.predict(test.X, t_test)
    mean_after, std_after = after.predict(test.X, t_test, return_std=True)
    rms_before, rms_after = rms(mean_before, test.Y), rms(mean_after, test.Y)
    print("test RMS per joint, before:", np.round(rms_before, 4), "after:", np.round(rms_after, 4))

    # The joint with the largest improvement, over a few seconds of the test log.
    j = int(np.argmax(rms_before - rms_after))
    t = test.t if test.t is not None else np.arange(test.size)
    shown = slice(0, min(test.size, 400))
    fig, axes = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    ax = axes[0]
    ax.plot(t[shown], test.Y[shown, j], color="black", lw=1.0, label="measured")
    ax.plot(t[shown], mean_before[shown, j], color="tab:red", lw=1.0,
            label=f"{before.spec} (RMS {rms_before[j]:.3g})")
    ax.plot(t[shown], mean_after[shown, j], color="tab:blue", lw=1.0,
            label=f"{after.spec} (RMS {rms_after[j]:.3g})")
    ax.fill_between(t[shown], mean_after[shown, j] - 2 * std_after[shown, j],
                    mean_after[shown, j] + 2 * std_after[shown, j], color="tab:blue", alpha=0.2,
                    lw=0)
    ax.set_ylabel(f"torque of joint {j + 1}")
    ax.set_title("unseen fast log: before and after the diagnosis")
    ax.legend(fontsize=8, loc="upper right")
    ax = axes[1]
    ax.plot(t[shown], test.Y[shown, j] - mean_before[shown, j], color="tab:red", lw=1.0,
            label="error before")
    ax.plot(t[shown], test.Y[shown, j] - mean_after[shown, j], color="tab:blue", lw=1.0,
            label="error after")
    ax.set_xlabel("t (s)" if test.t is not None else "sample")
    ax.set_ylabel("measured - predicted")
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
