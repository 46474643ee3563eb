#!/usr/bin/python3
"""Run every shipped scene (short) and every reference case with one tetfsi executable, for a
before/after comparison of a change that should not change results.

Usage: run_cases.py TETFSI OUT_ROOT [--steps N] [--only NAME,...] [--threads T]
  Runs data/scenes/<name>.json for N steps (default 3, a frame every step) into
  OUT_ROOT/<name>, and each case of tests/reference/manifest.json (its scene, steps and --set
  overrides) into OUT_ROOT/ref_<case>. Prints one line per run with its wall seconds.
Compare two such roots: run_cases.py --compare ROOT_A ROOT_B (scripts/compare_runs.py on each
pair of folders; exit 1 if any differs).
"""
import argparse, json, os, subprocess, sys, time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def cases(steps, only):
    out = []
    for f in sorted(os.listdir(os.path.join(ROOT, "data", "scenes"))):
        if f.endswith(".json"):
            out.append((f[:-5], os.path.join("data", "scenes", f), steps, ["output.every=1"]))
    with open(os.path.join(ROOT, "tests", "reference", "manifest.json")) as f:
        for c in json.load(f)["cases"]:
            out.append(("ref_" + c["name"], c["scene"], c["steps"], c.get("set", [])))
    return [c for c in out if not only or c[0] in only]


def run(exe, root, steps, only, threads):
    failed = 0
    for name, scene, n, sets in cases(steps, only):
        cmd = [exe, "run", scene, "--out", os.path.join(root, name), "--steps", str(n),
               "--progress", "off", "--threads", str(threads)]
        for s in sets:
            cmd += ["--set", s]
        t0 = time.time()
        r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
        status = "ok" if r.returncode == 0 else f"exit {r.returncode}: {r.stderr.strip()[-200:]}"
        failed += r.returncode != 0
        print(f"{name:28s} {n:3d} steps {time.time() - t0:7.1f} s  {status}", flush=True)
    return 1 if failed else 0


def compare(a, b):
    differ = 0
    for name in sorted(os.listdir(a)):
        if not os.path.isdir(os.path.join(a, name)):
            continue
        r = subprocess.run(["/usr/bin/python3", os.path.join(HERE, "compare_runs.py"),
                            os.path.join(a, name), os.path.join(b, name)],
                           capture_output=True, text=True)
        last = (r.stdout.strip().splitlines() or [r.stderr.strip()])[-1]
        print(f"{name:28s} {last}")
        differ += r.returncode != 0
    print(f"{differ} run(s) differ")
    return 1 if differ else 0


def main():
    if len(sys.argv) == 4 and sys.argv[1] == "--compare":
        return compare(sys.argv[2], sys.argv[3])
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("tetfsi")
    p.add_argument("out_root")
    p.add_argument("--steps", type=int, default=3)
    p.add_argument("--only", default="")
    p.add_argument("--threads", type=int, default=2)
    a = p.parse_args()
    only = set(x for x in a.only.split(",") if x)
    return run(os.path.abspath(a.tetfsi), os.path.abspath(a.out_root), a.steps, only, a.threads)


if __name__ == "__main__":
    sys.exit(main())
