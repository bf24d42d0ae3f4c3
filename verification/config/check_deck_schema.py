#!/usr/bin/python3
"""The deck schema (`rkfem schema`) and the deck reader agree.

usage: check_deck_schema.py RKFEM REPO

- the three schemas (run deck, material-point deck, study file) are valid draft-07 schemas;
- every example deck, material-point deck and study file in REPO/studies validates against its
  schema, and the reader takes it (`rkfem check`, `rkfem material-point`, `rkfem study --only`);
  so does the deck `rkfem import` makes of the keyword Taylor bar;
- a set of bad decks (each one change to a good one: a misspelled key, a unit of another
  dimension, a choice that is not one, a missing required key, a list of the wrong length, ...)
  is refused by both, the schema and the reader.
Prints what it checked; exits non-zero with the disagreements.
"""
import copy
import json
import os
import subprocess
import sys
import tempfile

try:
    import jsonschema
    import yaml
except ImportError as e:  # Debian's python3-jsonschema and python3-yaml (scripts/install-deps)
    sys.exit("check_deck_schema.py needs python3-jsonschema and python3-yaml: %s" % e)

rkfem, repo = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
work = tempfile.mkdtemp()
errors = []


def schema(root):
    out = subprocess.run([rkfem, "schema", root], check=True, capture_output=True, text=True).stdout
    s = json.loads(out)
    jsonschema.Draft7Validator.check_schema(s)
    return jsonschema.Draft7Validator(s)


validators = {root: schema(root) for root in ("deck", "material-point", "study")}


def schema_errors(root, doc):
    return sorted(validators[root].iter_errors(doc), key=lambda e: list(e.absolute_path))


def reader_accepts(root, path):
    if root == "deck":
        cmd = [rkfem, "check", path]
    elif root == "material-point":
        cmd = [rkfem, "material-point", path, "--out", os.path.join(work, "mp"), "--quiet"]
    else:  # reads the study file and its decks, runs no case
        cmd = [rkfem, "study", path, "--out", os.path.join(work, "study"), "--only", "no-such-case", "--quiet"]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    # a study with --only of no case reads everything and then says no case matched (exit 2)
    if root == "study":
        return "'no-such-case' is not a case of" in r.stderr, r.stderr
    return r.returncode == 0, r.stderr


def good(root, path):
    with open(path) as f:
        doc = yaml.safe_load(f)
    errs = schema_errors(root, doc)
    ok, stderr = reader_accepts(root, path)
    if errs:
        errors.append("%s: the schema refuses a deck the reader %s: %s at %s" %
                      (path, "takes" if ok else "refuses too", errs[0].message[:200],
                       "/".join(map(str, errs[0].absolute_path))))
    if not ok:
        errors.append("%s: the reader refuses an example: %s" % (path, stderr.strip()[-300:]))
    return not errs and ok


counts = {}
for root, folder in (("deck", "decks"), ("material-point", "material_points"), ("study", "tables")):
    d = os.path.join(repo, "studies", folder)
    files = sorted(f for f in os.listdir(d) if f.endswith(".yaml"))
    counts[root] = sum(good(root, os.path.join(d, f)) for f in files), len(files)

# a deck the keyword importer writes
imported = os.path.join(work, "imported.yaml")
kfile = os.path.join(repo, "verification", "fuzz_regressions", "keyword_taylor_bar.k")
with open(imported, "w") as f:
    subprocess.run([rkfem, "import", kfile, "--units", "mm-ms-kg-kN"], check=True, stdout=f,
                   stderr=subprocess.DEVNULL)
# the deck names the mesh file relative to its folder
with open(imported) as f:
    text = f.read().replace("file: keyword_taylor_bar.k", "file: " + kfile)
with open(imported, "w") as f:
    f.write(text)
counts["imported"] = int(good("deck", imported)), 1

# bad decks: one change each to the column deck
with open(os.path.join(repo, "studies", "decks", "column_wave.yaml")) as f:
    base = yaml.safe_load(f)
part = next(iter(base["parts"]))


def change(fn):
    d = copy.deepcopy(base)
    fn(d)
    return d


def set_path(d, path, value):
    *keys, last = path
    for k in keys:
        d = d[k]
    d[last] = value


def delete(d, path):
    *keys, last = path
    for k in keys:
        d = d[k]
    del d[last]


P = ["parts", part]
bad = {
    "a misspelled top-level key": change(lambda d: d.update(tiem=d.pop("time"))),
    "a time in a pressure unit": change(lambda d: set_path(d, ["time", "end"], "5 MPa")),
    "a dimensionless factor with a unit": change(lambda d: set_path(d, ["time", "dt_scale"], "0.5 ms")),
    "a stepper that is none": change(lambda d: set_path(d, ["time", "stepper"], "leapfrog")),
    "a formulation that is none": change(lambda d: set_path(d, P + ["formulation"], "fem-8pt")),
    "a missing end time": change(lambda d: delete(d, ["time", "end"])),
    "a material model that is none": change(lambda d: set_path(d, P + ["material", "model"], "plastic")),
    "an unknown generator key": change(lambda d: set_path(d, P + ["generator", "elements"], 10)),
    "a coefficient that is no number": change(lambda d: set_path(d, P + ["hourglass"], {"coefficient": "a lot"})),
    "a vector of two components": change(lambda d: set_path(d, P + ["initial_velocity"], ["1 m/s", "2 m/s"])),
    "a contact type that is none": change(lambda d: set_path(d, ["contacts"], [{"type": "glue", "surfaces": [part]}])),
    "no parts": change(lambda d: delete(d, ["parts"])),
    "conditions as a mapping": change(lambda d: set_path(d, ["boundary_conditions"], {"node_set": "x"})),
    "a density in a length unit": change(lambda d: set_path(d, P + ["material", "rho"], "7850 mm")),
    "an RK order of 3": change(lambda d: set_path(d, P + ["rk"], {"order": 3})),
    "a selector without its type": change(lambda d: set_path(d, ["node_sets"], {"s": {"select": {"name": "zmin"}}})),
}
refused = 0
for what, doc in bad.items():
    path = os.path.join(work, "bad.yaml")
    with open(path, "w") as f:
        yaml.safe_dump(doc, f)
    errs = schema_errors("deck", doc)
    ok, stderr = reader_accepts("deck", path)
    if not errs:
        errors.append("bad deck (%s): the schema takes it" % what)
    if ok:
        errors.append("bad deck (%s): the reader takes it" % what)
    refused += bool(errs) and not ok
    print("bad deck, %s: schema: %s; reader: %s" % (what, errs[0].message[:90] if errs else "takes it",
                                                    stderr.strip().splitlines()[-1][:120] if not ok else "takes it"))
counts["bad decks refused by both"] = refused, len(bad)

for k, (n, total) in counts.items():
    print("%s: %d of %d" % (k, n, total))
sys.exit("; ".join(errors) or None)
