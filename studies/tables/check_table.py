#!/usr/bin/python3
"""Asserts a study's table: every row of METRIC in the listed cases (or every case with a published
value) completed and lies within TOL (relative) of its published value, and/or between --min
and --max (absolute, in the metric's unit).
  check_table.py DIR/table.csv --metric peak_stress --within 0.02 [--cases a,b]
  check_table.py DIR/table.csv --metric implosion_pressure --min 1112 --cases fe_08in
  check_table.py DIR/table.csv --metric crater_depth --min-metric apparent_depth --cases 1.3
    (at least the same case's apparent_depth, in the same unit)"""
import argparse, csv, sys

ap = argparse.ArgumentParser()
ap.add_argument('table')
ap.add_argument('--metric', required=True)
ap.add_argument('--within', type=float)
ap.add_argument('--min', type=float)
ap.add_argument('--max', type=float)
ap.add_argument('--min-metric')
ap.add_argument('--cases', default='')
a = ap.parse_args()
if a.within is None and a.min is None and a.max is None and a.min_metric is None:
    sys.exit('check_table: give --within, --min, --max or --min-metric')
rows = list(csv.DictReader(open(a.table)))
other = {(r['case'], r['unit']): r['ours'] for r in rows if a.min_metric and r['metric'] == a.min_metric}
cases = [c for c in a.cases.split(',') if c]
bad, seen = [], 0
for r in rows:
    if r['metric'] != a.metric or (cases and r['case'] not in cases) or (not cases and r['published'] == ''):
        continue
    seen += 1
    ok = r['status'] in ('completed', 'reused') and r['ours'] != ''
    if ok and a.within is not None:
        ok = r['rel_diff'] != '' and abs(float(r['rel_diff'])) <= a.within
    if ok and a.min is not None:
        ok = float(r['ours']) >= a.min
    if ok and a.max is not None:
        ok = float(r['ours']) <= a.max
    if ok and a.min_metric:
        floor = other.get((r['case'], r['unit']), '')
        ok = floor != '' and float(r['ours']) >= float(floor)
    print(f"{r['case']:20s} {a.metric} {r['ours']:>14s} {r['unit']} published {r['published']} "
          f"rel {r['rel_diff'] or '-':>12s} {'ok' if ok else 'OUT OF BAND'}")
    if not ok:
        bad.append(r['case'])
if seen == 0 or (cases and seen != len(cases)):
    sys.exit(f"check_table: expected rows of {a.metric} with published values for {cases or 'some case'}, found {seen}")
sys.exit(f"check_table: {', '.join(bad)} out of band" if bad else 0)
