#!/usr/bin/env python3
"""Which lines and branches of the project each test runs, and the tests that the sanitizer
pass can leave to the Release pass because the other tests run everything they run.

The sanitizer pass of scripts/run-tests.sh runs the suite again under AddressSanitizer +
UndefinedBehaviorSanitizer, at several times the Release pass's cost. The sanitizers check the
code that runs; a test whose lines and branch outcomes all run in other tests of the pass adds
no code to what they check (it may add other sizes and values of the same code). This script
measures which tests those are:

  1. every test of a coverage tree (below) that the sanitizer tree also has, except those of
     tests/release_only.txt, runs alone with its own profile (the programs it starts, such as
     the structgp program, write theirs next to it);
  2. per test, the lines and branch outcomes of src/, include/ and examples/ that ran;
  3. a weighted set cover: tests are kept in order of the most new lines and branch outcomes
     per second of sanitizer time (the sanitizer tree's CTestCostData.txt; a test it lacks
     counts three times its coverage run) until the kept tests run all that the whole pass
     runs; then every kept test whose items the other kept tests all run is dropped again,
     the costliest first.

It writes the tests that are not kept, one anchored pattern per line in the format of
tests/release_only.txt (--write tests/sanitizer_redundant.txt), each with its sanitizer time and
the kept test that shares most of its items, and prints what it measured.

The coverage tree is configured as scripts/run-tests.sh configures its ASan tree, with
coverage in place of the sanitizers:

  CC=clang CXX=clang++ cmake -S . -B build-cov -G Ninja -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_CXX_FLAGS_RELEASE="-O1 -DNDEBUG" \
    -DCMAKE_CXX_FLAGS="-fprofile-instr-generate -fcoverage-mapping" \
    -DCMAKE_EXE_LINKER_FLAGS=-fprofile-instr-generate \
    -DSTRUCTGP_BUILD_BENCHMARKS=OFF -DSTRUCTGP_BUILD_EXPERIMENTS=OFF -DSTRUCTGP_PYTHON=OFF
  ninja -C build-cov
  scripts/coverage-per-test.py --build-dir build-cov --sanitizer-tree build-asan \
    --out /tmp/coverage --write tests/sanitizer_redundant.txt
"""
import argparse
import concurrent.futures
import json
import os
import re
import shutil
import subprocess
import sys
import time


def ctest_tests(build_dir):
    out = subprocess.run(["ctest", "--test-dir", build_dir, "--show-only=json-v1"],
                         check=True, capture_output=True, text=True).stdout
    tests = []
    for t in json.loads(out)["tests"]:
        props = {p["name"]: p["value"] for p in t.get("properties", [])}
        env = dict(e.split("=", 1) for e in props.get("ENVIRONMENT", []))
        tests.append({"name": t["name"], "command": t["command"],
                      "cwd": props.get("WORKING_DIRECTORY", build_dir), "env": env,
                      "timeout": float(props.get("TIMEOUT", 1500))})
    return tests


HEADER = """\
# Tests that the sanitizer pass of scripts/run-tests.sh leaves to the Release pass: every line
# and branch outcome of src/, include/ and examples/ that each of them runs also runs in the
# tests of that pass that are not listed here (measured with a coverage tree, and chosen to
# save the most sanitizer time: scripts/coverage-per-test.py, which wrote this file; run it
# again when tests are added or renamed, docs/reliability.md section 5). The format of
# tests/release_only.txt: one ctest name pattern per line, anchored by the script; '#' starts
# a comment (here: the test's time under ASan + UBSan, and the kept test that shares most of
# what it runs).
# {summary}.

"""


def run_one(test, prof_dir):
    os.makedirs(prof_dir, exist_ok=True)
    env = dict(os.environ)
    env.update(test["env"])
    env["LLVM_PROFILE_FILE"] = os.path.join(prof_dir, "%p-%m.profraw")
    start = time.monotonic()
    try:
        proc = subprocess.run(test["command"], cwd=test["cwd"], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              timeout=test["timeout"])
        status = proc.returncode
    except subprocess.TimeoutExpired:
        status = "timeout"
    return time.monotonic() - start, status


def covered_items(prof_dir, objects, source_root):
    raws = [os.path.join(prof_dir, f) for f in os.listdir(prof_dir) if f.endswith(".profraw")]
    if not raws:
        return set()
    profdata = os.path.join(prof_dir, "merged.profdata")
    subprocess.run(["llvm-profdata", "merge", "-sparse", "-o", profdata] + raws, check=True)
    cmd = ["llvm-cov", "export", "-format=lcov", "-instr-profile", profdata, objects[0]]
    for o in objects[1:]:
        cmd += ["-object", o]
    lcov = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    items = set()
    source = None
    for line in lcov.splitlines():
        if line.startswith("SF:"):
            path = os.path.realpath(line[3:])
            rel = os.path.relpath(path, source_root)
            source = rel if (rel.startswith(("src/", "include/", "examples/"))) else None
        elif source is None:
            continue
        elif line.startswith("DA:"):
            number, count = line[3:].split(",")[:2]
            if int(count) > 0:
                items.add(f"{source}:{number}")
        elif line.startswith("BRDA:"):
            number, block, branch, taken = line[5:].split(",")
            if taken not in ("-", "0"):
                items.add(f"{source}:{number}:b{block}.{branch}")
    return items


def objects_of(test, build_dir):
    """The test's program, and the programs it may start (the CLI, a program named in its
    arguments)."""
    objects = [test["command"][0]]
    for extra in ("src/cli/structgp",):
        path = os.path.join(build_dir, extra)
        if os.path.exists(path) and path not in objects:
            objects.append(path)
    for word in test["command"][1:]:
        # A program given as an argument, or as a definition (cmake -DPROGRAM=path -P script).
        path = word.split("=", 1)[1] if word.startswith("-D") and "=" in word else word
        if os.path.isfile(path) and os.access(path, os.X_OK) and path not in objects:
            objects.append(path)
    return objects


def read_patterns(path):
    """The anchored patterns of tests/release_only.txt (as scripts/run-tests.sh reads it)."""
    patterns = []
    with open(path) as f:
        for line in f:
            line = line.split("#", 1)[0].rstrip()
            if line:
                patterns.append("^" + line + "$")
    return patterns


def read_costs(path):
    """CTestCostData.txt: 'name runs seconds' per line (names may hold spaces)."""
    costs = {}
    if not os.path.exists(path):
        return costs
    with open(path) as f:
        for line in f:
            fields = line.rstrip("\n").rsplit(" ", 2)
            if len(fields) == 3:
                try:
                    costs[fields[0]] = float(fields[2])
                except ValueError:
                    pass
    return costs


def test_pattern(name):
    """An anchored-by-the-reader ctest pattern for one test. A parameterised test's name ends in
    '  # GetParam() = k', and '#' starts a comment in the list: its name up to there is unique."""
    if " # " in name:
        return re.sub(r"([][.*+?()^$|\\])", r"\\\1", name.split(" # ")[0].rstrip()) + " .*"
    return re.sub(r"([][.*+?()^$|\\])", r"\\\1", name)


def ctest_names(build_dir):
    out = subprocess.run(["ctest", "--test-dir", build_dir, "-N"], check=True,
                         capture_output=True, text=True).stdout
    return {m.group(1) for m in re.finditer(r"^\s*Test\s+#\d+: (.*)$", out, re.M)}


def select(tests, items, cost, keep_patterns):
    """Weighted greedy set cover, then the reverse pass."""
    universe = set().union(*items.values())
    kept = [t for t in tests if any(re.search(p, t) for p in keep_patterns)]
    covered = set().union(*(items[t] for t in kept)) if kept else set()
    candidates = [t for t in tests if t not in kept]
    while covered != universe:
        best = max(candidates, key=lambda t: len(items[t] - covered) / max(cost[t], 0.05))
        if not items[best] - covered:
            break
        kept.append(best)
        candidates.remove(best)
        covered |= items[best]
    for t in sorted(kept, key=lambda t: -cost[t]):
        if any(re.search(p, t) for p in keep_patterns):
            continue
        others = set().union(*(items[o] for o in kept if o != t))
        if items[t] <= others:
            kept.remove(t)
    return kept, universe


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--build-dir", required=True, help="the coverage tree")
    parser.add_argument("--out", required=True, help="directory for the profiles and results")
    parser.add_argument("--sanitizer-tree", required=True,
                        help="the ASan tree: its tests, and its CTestCostData.txt when it has one")
    parser.add_argument("--write", help="the file to write the patterns of the tests not kept to")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 2)
    parser.add_argument("--keep", nargs="*", default=[],
                        help="regular expressions of tests always kept")
    parser.add_argument("--exclude-file",
                        default=os.path.join(os.path.dirname(__file__), "..", "tests",
                                             "release_only.txt"),
                        help="tests neither run nor counted (default: tests/release_only.txt)")
    parser.add_argument("--reuse", action="store_true",
                        help="reuse the coverage of an earlier run in --out")
    args = parser.parse_args()
    source_root = os.path.realpath(os.path.join(os.path.dirname(__file__), ".."))
    build_dir = os.path.realpath(args.build_dir)
    results_path = os.path.join(args.out, "coverage.json")

    sanitizer_tests = ctest_names(args.sanitizer_tree)
    tests = [t for t in ctest_tests(build_dir) if t["name"] in sanitizer_tests]
    if args.exclude_file:
        tests = [t for t in tests if not any(re.search(p, t["name"])
                                             for p in read_patterns(args.exclude_file))]
    results = {}
    if args.reuse and os.path.exists(results_path):
        with open(results_path) as f:
            results = json.load(f)
    todo = [t for t in tests if t["name"] not in results]

    def measure(index_test):
        index, test = index_test
        prof_dir = os.path.join(args.out, "profiles", str(index))
        shutil.rmtree(prof_dir, ignore_errors=True)
        seconds, status = run_one(test, prof_dir)
        found = covered_items(prof_dir, objects_of(test, build_dir), source_root)
        shutil.rmtree(prof_dir, ignore_errors=True)
        return test["name"], {"seconds": seconds, "status": status, "items": sorted(found)}

    with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        for done, (name, result) in enumerate(pool.map(measure, enumerate(todo)), 1):
            results[name] = result
            print(f"[{done}/{len(todo)}] {name}: {result['seconds']:.1f} s, "
                  f"{len(result['items'])} items, status {result['status']}", file=sys.stderr)
    os.makedirs(args.out, exist_ok=True)
    with open(results_path, "w") as f:
        json.dump(results, f)

    failed = [n for n, r in results.items() if r["status"] != 0]
    if failed:
        print("tests that did not pass in the coverage tree (kept):", *failed, sep="\n  ",
              file=sys.stderr)
    names = [t["name"] for t in tests]
    costs = read_costs(os.path.join(args.sanitizer_tree, "Testing", "Temporary",
                                    "CTestCostData.txt"))
    cost = {n: costs.get(n, 3 * results[n]["seconds"]) for n in names}
    items = {n: set(results[n]["items"]) for n in names}
    keep = args.keep + ["^" + re.escape(n) + "$" for n in failed]
    kept, universe = select(names, items, cost, keep)
    left = [n for n in names if n not in kept]
    total = sum(cost[n] for n in names)
    kept_cost = sum(cost[n] for n in kept)
    summary = (f"{len(universe)} lines and branch outcomes of src/, include/ and examples/ run by "
               f"{len(names)} tests ({total:.0f} s of sanitizer time); {len(kept)} tests run all "
               f"of them ({kept_cost:.0f} s); the {len(left)} others: {total - kept_cost:.0f} s")
    if args.keep:
        summary += f" (kept as well: the tests matching {', '.join(args.keep)})"
    print(summary)
    lines = []
    for n in sorted(left, key=lambda n: -cost[n]):
        if items[n]:
            best = test_pattern(max(kept, key=lambda k: len(items[n] & items[k])))
        else:
            best = "runs no line of src/, include/ or examples/"
        lines.append(f"{test_pattern(n)}   # {cost[n]:.1f} s; {best}")
    if args.write:
        with open(args.write, "w") as f:
            f.write(HEADER.format(summary=summary))
            f.write("\n".join(lines) + "\n")
    else:
        print("\n".join(lines))

if __name__ == "__main__":
    main()
