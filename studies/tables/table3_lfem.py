#!/usr/bin/python3
"""Seed Table 3, LFEM rows (Problem 6): runs studies/decks/p6_fsp_cylinder.yaml per case and writes
DIR/table.csv and DIR/table.md with the published values beside ours (until `rkfem study` lands,
issue #18, this script is the study).

Usage: studies/tables/table3_lfem.py RKFEM_EXE --out DIR [--smoke | --long] [--cases 1.5,1.4]
  default: cases 1.2-1.5 and 3.1-3.4 (target 2, 1, 1/2, 1/4 in); --long adds 1.1 (1/8 in);
  --smoke: case 1.5 alone (2 in, about 2 s), what CI runs.
A case whose DIR/CASE/summary.json holds the same overrides and completed is not run again.

Published values: the seed's Table 3 (KC-FEMFRE paper, Choi, Crawford & Wu), columns energy ratio
(hourglass / total, %), apparent and actual crater depth (in). Cases 3.1-3.4 use f'c 25 MPa (its
footnote 6). The seed gives no difference between cases 3.3 and 3.4 (both IHQ 5, QM 0.01); both
run the same here. Hourglass: IHQ 3 (Flanagan-Belytschko viscous) is our viscous form, IHQ 5
(stiffness) our stiffness form.
"""
import argparse
import json
import os
import subprocess
import sys

INCH = 0.0254
# case: (target element size [in], f'c [MPa], hourglass type, QM, published (ratio %, apparent in, actual in))
CASES = {
    "1.1": ("1/8", 35, "viscous", 0.14, (10.0, 1.21, 1.45)),
    "1.2": ("1/4", 35, "viscous", 0.14, (26.0, 1.12, 1.35)),
    "1.3": ("1/2", 35, "viscous", 0.14, (43.5, 0.81, 1.17)),
    "1.4": ("1", 35, "viscous", 0.14, (49.2, 0.48, 0.74)),
    "1.5": ("2", 35, "viscous", 0.14, (32.3, 0.21, None)),
    "3.1": ("1/2", 25, "viscous", 0.14, (45.2, 0.90, 1.64)),
    "3.2": ("1/2", 25, "viscous", 0.04, (33.1, 1.30, 1.61)),
    "3.3": ("1/2", 25, "stiffness", 0.01, (11.8, 1.50, 1.98)),
    "3.4": ("1/2", 25, "stiffness", 0.01, (13.7, 1.65, 2.19)),
}


def size_in(text):
    if "/" in text:
        a, b = text.split("/")
        return float(a) / float(b)
    return float(text)


def overrides(case):
    size, fc, hg, qm, _ = CASES[case]
    return [
        f"parts.target.generator.element_size={size_in(size) * INCH} m",
        f"parts.target.material.fc={fc} MPa",
        f"parts.target.hourglass.type={hg}",
        f"parts.target.hourglass.coefficient={qm}",
    ]


def run_case(exe, deck, out, case):
    run_dir = os.path.join(out, case)
    ov = overrides(case)
    summary = os.path.join(run_dir, "summary.json")
    if os.path.exists(summary):
        with open(summary) as f:
            s = json.load(f)
        if s.get("overrides") == ov and s.get("status") == "completed":
            return s, "reused"
    cmd = [exe, "run", deck, "--out", run_dir, "--quiet"]
    for o in ov:
        cmd += ["--set", o]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0 or not os.path.exists(summary):
        return {"status": "failed", "message": (r.stderr or r.stdout).strip().splitlines()[-1:]}, "failed"
    with open(summary) as f:
        return json.load(f), "ran"


def rel(ours, published):
    if published is None or ours is None or published == 0:
        return ""
    return f"{100.0 * (ours - published) / published:+.0f}%"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("exe")
    ap.add_argument("--out", required=True)
    ap.add_argument("--smoke", action="store_true")
    ap.add_argument("--long", action="store_true")
    ap.add_argument("--cases")
    a = ap.parse_args()
    here = os.path.dirname(os.path.abspath(__file__))
    deck = os.path.join(here, "..", "decks", "p6_fsp_cylinder.yaml")
    if a.cases:
        cases = a.cases.split(",")
    elif a.smoke:
        cases = ["1.5"]
    else:
        cases = ["1.2", "1.3", "1.4", "1.5", "3.1", "3.2", "3.3", "3.4"] + (["1.1"] if a.long else [])
    for c in cases:
        if c not in CASES:
            sys.exit(f"table3_lfem: unknown case '{c}'; expected one of {', '.join(CASES)}")
    os.makedirs(a.out, exist_ok=True)
    rows = []
    for k, c in enumerate(cases):
        print(f"table3_lfem: case {c} ({k + 1}/{len(cases)}) ...", file=sys.stderr, flush=True)
        s, how = run_case(a.exe, deck, a.out, c)
        size, fc, hg, qm, pub = CASES[c]
        row = {"case": c, "size_in": size, "fc_MPa": fc, "hourglass": hg, "QM": qm, "status": s.get("status"),
               "how": how, "pub_ratio_pct": pub[0], "pub_apparent_in": pub[1], "pub_actual_in": pub[2]}
        if s.get("status") == "completed":
            im = s["impact"]
            row.update({"ratio_pct": 100.0 * s["hourglass_to_total"], "apparent_in": im["apparent_depth"] / INCH,
                        "actual_in": im["actual_depth"] / INCH, "residual_velocity": im["residual_velocity"],
                        "max_balance_error": s["max_balance_error"], "steps": s["steps"],
                        "wall_seconds": s["wall_seconds"], "elements": s["elements"]})
        else:
            row["message"] = " ".join(s.get("message", []) if isinstance(s.get("message"), list) else [s.get("message", "")])
        rows.append(row)
        print(f"table3_lfem: case {c}: {how}, {row['status']}", file=sys.stderr, flush=True)
    cols = ["case", "size_in", "fc_MPa", "hourglass", "QM", "status", "pub_ratio_pct", "ratio_pct", "pub_apparent_in",
            "apparent_in", "pub_actual_in", "actual_in", "residual_velocity", "max_balance_error", "steps",
            "wall_seconds", "elements"]
    with open(os.path.join(a.out, "table.csv"), "w") as f:
        f.write(",".join(cols) + "\n")
        for r in rows:
            f.write(",".join("" if r.get(c) is None else str(r.get(c)) for c in cols) + "\n")
    fmt = lambda v, p=2: "N/A" if v is None else f"{v:.{p}f}"
    with open(os.path.join(a.out, "table.md"), "w") as f:
        f.write("Seed Table 3, LFEM rows (Problem 6): published (LS-DYNA, in the seed) | rkfem\n\n")
        f.write("| case | size in | f'c MPa | hourglass, QM | energy ratio % pub | ours | apparent in pub | ours | diff |"
                " actual in pub | ours | diff | status |\n|" + "---|" * 13 + "\n")
        for r in rows:
            ok = r["status"] == "completed"
            f.write(f"| {r['case']} | {r['size_in']} | {r['fc_MPa']} | {r['hourglass']} {r['QM']} | "
                    f"{fmt(r['pub_ratio_pct'], 1)} | {fmt(r.get('ratio_pct'), 1) if ok else '-'} | "
                    f"{fmt(r['pub_apparent_in'])} | {fmt(r.get('apparent_in')) if ok else '-'} | "
                    f"{rel(r.get('apparent_in'), r['pub_apparent_in']) if ok else ''} | "
                    f"{fmt(r['pub_actual_in'])} | {fmt(r.get('actual_in')) if ok else '-'} | "
                    f"{rel(r.get('actual_in'), r['pub_actual_in']) if ok else ''} | "
                    f"{r['status']}{'' if ok else ': ' + r.get('message', '')} |\n")
    print(open(os.path.join(a.out, "table.md")).read())
    return 0 if all(r["status"] == "completed" for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
