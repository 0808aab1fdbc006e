#!/usr/bin/env python3
"""Computed torque on the arms with each velocity source, over seeds, paired by seed.

  python3 scripts/velocity_study.py [--bin target/release/evoloop] [--seeds 10] [--out DIR]

For arm3_ct and arm7_ct (lockstep, 10 s, the scenario's encoder noise 1e-4 rad) it runs
computed torque with `velocity = "true"` (the simulator's qd_true, an ideal sensor no arm has),
`"filtered"` (differenced encoder positions, 50 Hz low-pass) and `"observer"` (the law's model
predicting from the applied torques, 50 Hz error bandwidth), once with the controller's model
equal to the arm and once with a model wrong the way a CAD model is (each link's mass and
inertia scaled by a fixed factor in 0.8-1.2, written into DIR: WRONG[k] for the k-th
[[joint]] of a D-H file, for the k-th <link> of a URDF, whose first link is the base). The seed moves the encoder
noise. It prints, per case, the median tracking RMS after the first second (all joints, mrad)
and the exact two-sided Wilcoxon signed-rank test of observer against filtered, and writes the
rows to DIR/velocity_study.csv. Standard library only (and scripts/rkgnn_ablation.py's test)."""
import argparse
import csv
import json
import os
import re
import statistics
import subprocess
import sys

from rkgnn_ablation import wilcoxon_p  # scripts/ is on the path of a script run from it

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# Fixed before measuring: per link, the factor on its mass and inertia in the wrong model.
WRONG = [1.2, 0.85, 1.1, 0.9, 1.15, 0.8, 1.05]


def beside(name, rel):
    """A path `rel` of scenario `name` (`arm3/arm3_ct`), which is relative to the scenario's folder."""
    return os.path.normpath(os.path.join(ROOT, "config", os.path.dirname(name), rel))


def wrong_model(robot, out):
    """The robot file with link k's mass and inertia scaled by WRONG[k] (a D-H .toml, or a URDF)."""
    text = open(robot).read()
    if robot.endswith(".toml"):
        parts = text.split("[[joint]]")
        for k in range(1, len(parts)):
            f = WRONG[(k - 1) % len(WRONG)]
            parts[k] = re.sub(r"(?m)^mass = ([0-9.eE+-]+)",
                              lambda m: f"mass = {float(m.group(1)) * f!r}", parts[k])
            parts[k] = re.sub(r"(?m)^inertia = \[([^\]]*)\]",
                              lambda m: "inertia = [" + ", ".join(
                                  repr(float(v) * f) for v in m.group(1).split(",")) + "]",
                              parts[k])
        text = "[[joint]]".join(parts)
    else:
        k = -1

        def link(m):
            nonlocal k
            k += 1
            return m.group(0)

        def scale(m):
            f = WRONG[max(k, 0) % len(WRONG)]
            attrs = re.sub(r'(\w+)="([0-9.eE+-]+)"',
                           lambda a: f'{a.group(1)}="{float(a.group(2)) * f!r}"', m.group(0))
            return attrs

        out_text, pos = [], 0
        for m in re.finditer(r"<link\b|<mass [^>]*>|<inertia [^>]*>", text):
            out_text.append(text[pos:m.start()])
            out_text.append(link(m) if m.group(0) == "<link" else scale(m))
            pos = m.end()
        out_text.append(text[pos:])
        text = "".join(out_text)
    path = os.path.join(out, "wrong_" + os.path.basename(robot))
    open(path, "w").write(text)
    return path


def scenario(name, velocity, model, out):
    """The shipped scenario with `velocity` and the controller's `model`, written into `out`."""
    text = open(os.path.join(ROOT, "config", name + ".toml")).read()
    text = re.sub(r'(?m)^robot = "([^"]+)"',
                  lambda m: f'robot = "{beside(name, m.group(1))}"', text)
    text = re.sub(r'(?m)^velocity = "[a-z]+"\n', "", text)  # the file's own choice
    extra = f'velocity = "{velocity}"\n'
    if model:
        extra += f'model = "{model}"\n'
    text = text.replace("[controller.computed_torque]\n", "[controller.computed_torque]\n" + extra, 1)
    stem = name.replace("/", "-")
    path = os.path.join(out, f"{stem}-{velocity}-{'wrong' if model else 'true'}.toml")
    open(path, "w").write(text)
    return path


def rms_after_1s(binary, config, seed, out):
    run = os.path.join(out, "run")
    subprocess.run([binary, "run", config, "--seed", str(seed), "--out", run, "--quiet"],
                   check=True, stdout=subprocess.DEVNULL)
    return 1e3 * json.load(open(os.path.join(run, "summary.json")))["tracking_after_1s"]["rms_all"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bin", default=os.path.join(ROOT, "target/release/evoloop"))
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--out", default=os.path.join(ROOT, "runs/velocity_study"))
    ap.add_argument("--arms", default="arm3/arm3_ct,arm7/arm7_ct")
    a = ap.parse_args()
    a.out = os.path.abspath(a.out)
    os.makedirs(a.out, exist_ok=True)
    rows = []
    for name in a.arms.split(","):
        robot = beside(name, re.search(r'(?m)^robot = "([^"]+)"',
                                       open(os.path.join(ROOT, "config", name + ".toml")).read()).group(1))
        for model in (None, wrong_model(robot, a.out)):
            res = {}
            for velocity in ("true", "filtered", "observer"):
                cfg = scenario(name, velocity, model, a.out)
                res[velocity] = [rms_after_1s(a.bin, cfg, s, a.out) for s in range(1, a.seeds + 1)]
                for s, v in enumerate(res[velocity], 1):
                    rows.append([name, "wrong" if model else "true", velocity, s, v])
            p = wilcoxon_p(res["observer"], res["filtered"])
            lower = sum(o < f for o, f in zip(res["observer"], res["filtered"]))
            med = {k: statistics.median(v) for k, v in res.items()}
            print(f"{name}, {'wrong' if model else 'true'} model: median rms after 1 s, mrad: "
                  f"true velocity {med['true']:.4f}, filtered {med['filtered']:.4f}, "
                  f"observer {med['observer']:.4f}; observer lower on {lower} of {a.seeds} "
                  f"seeds, exact Wilcoxon p = {p:.4g}", flush=True)
    with open(os.path.join(a.out, "velocity_study.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["scenario", "model", "velocity", "seed", "rms_after_1s_mrad"])
        w.writerows(rows)


if __name__ == "__main__":
    sys.exit(main())
