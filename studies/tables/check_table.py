#!/usr/bin/python3
"""Asserts a study's table: every row of METRIC (in the listed cases, or all) that has a published
value lies within TOL (relative) of it, and the cases completed.
  check_table.py DIR/table.csv --metric peak_stress --within 0.02 [--cases a,b]"""
import argparse, csv, sys

ap = argparse.ArgumentParser()
ap.add_argument('table')
ap.add_argument('--metric', required=True)
ap.add_argument('--within', type=float, required=True)
ap.add_argument('--cases', default='')
a = ap.parse_args()
cases = [c for c in a.cases.split(',') if c]
bad, seen = [], 0
for r in csv.DictReader(open(a.table)):
    if r['metric'] != a.metric or (cases and r['case'] not in cases) or r['published'] == '':
        continue
    seen += 1
    ok = r['status'] in ('completed', 'reused') and r['rel_diff'] != '' and abs(float(r['rel_diff'])) <= a.within
    print(f"{r['case']:20s} {a.metric} {r['ours']:>14s} {r['unit']} published {r['published']} "
          f"rel {r['rel_diff'] or '-':>12s} {'ok' if ok else 'OUT OF BAND'}")
    if not ok:
        bad.append(r['case'])
if seen == 0 or (cases and seen != len(cases)):
    sys.exit(f"check_table: expected rows of {a.metric} with published values for {cases or 'some case'}, found {seen}")
sys.exit(f"check_table: {', '.join(bad)} outside {a.within}" if bad else 0)
