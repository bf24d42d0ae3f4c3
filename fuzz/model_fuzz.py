#!/usr/bin/python3
"""The model-build fuzzer: random valid decks through `rkfem check` and a few steps of `rkfem run`.

Each input is a deck drawn from a seed: one to three parts (box, cylinder, projectile, tube,
cloud, or an LS-DYNA keyword mesh whose nodes are perturbed), every formulation, material and
stabilization, RK supports, node and face sets, boundary conditions, loads, contacts between
parts stacked with a gap, erosion and conversion. A run of the sanitized build (the `asan`
preset: ASan + UBSan) must end in exit 0 (done), 2 (refused with a located line: a deck the
drawing made that the checks call bad, counted) or 3 (unstable, with its message); exit 1, a
signal, a hang (the timeout) or a sanitizer report is a failure, and its deck is kept.

Usage: fuzz/model_fuzz.py RKFEM_BINARY [--inputs N] [--seed S] [--seconds T] [--keep DIR]
Writes one line per input that fails, and a summary line with the counts.
"""
import argparse
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time

FORMULATIONS = ["fem-1pt", "fem-2x2x2", "fem-nodal", "rkpm"]


def mm(v):
    return f"{v:.4g} mm"


def material(r):
    kind = r.choice(["elastic", "elastic", "j2", "j2-eos", "kcc", "cscm"])
    if kind == "elastic":
        return "{model: elastic, rho: 7850 kg/m^3, E: %s GPa, nu: %.3f}" % (r.choice([70, 200, 210]), r.uniform(0.0, 0.45))
    if kind.startswith("j2"):
        eos = ", eos: {type: gruneisen, c0: 4578 m/s, s: 1.33, gamma0: 1.67, a: 0.43}" if kind == "j2-eos" else ""
        fail = ", fail: %.2f" % r.uniform(0.05, 1.5) if r.random() < 0.4 else ""
        cs = ", cowper_symonds: {C: 40, P: 5}" if r.random() < 0.3 else ""
        return "{model: j2, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3, sigy: %d MPa, etan: %d MPa%s%s%s}" % (
            r.randint(200, 1200), r.randint(0, 5000), fail, cs, eos)
    if kind == "kcc":
        rate = r.choice(["", ", rate_effects: true", ", rate_effects: false",
                         ", rate_effects: {law: ceb-fip, compression_cap: 2, tension_cap: none}"])
        return "{model: kcc, rho: 2400 kg/m^3, fc: %.1f MPa%s}" % (r.uniform(20, 150), rate)
    return "{model: cscm, rho: 2400 kg/m^3, fc: %.1f MPa, rate_effects: %s}" % (r.uniform(20, 58), r.choice(["true", "false"]))


def keyword_mesh(r, path, nx, ny, nz, h, z0):
    """A box of nx x ny x nz hexes of side h (mm) whose inner nodes move by up to 0.2 h."""
    with open(path, "w") as f:
        f.write("*KEYWORD\n*NODE\n")
        nid = lambda i, j, k: 1 + i + (nx + 1) * (j + (ny + 1) * k)
        for k in range(nz + 1):
            for j in range(ny + 1):
                for i in range(nx + 1):
                    inner = 0 < i < nx and 0 < j < ny and 0 < k < nz
                    d = [r.uniform(-0.2, 0.2) * h if inner else 0.0 for _ in range(3)]
                    f.write("%8d%16.8g%16.8g%16.8g\n" % (nid(i, j, k), i * h + d[0], j * h + d[1], z0 + k * h + d[2]))
        f.write("*ELEMENT_SOLID\n")
        eid = 100
        flip = r.randrange(nx * ny * nz) if r.random() < 0.1 else -1  # one solid inside out: refused, exit 2
        for k in range(nz):
            for j in range(ny):
                for i in range(nx):
                    n = [nid(i, j, k), nid(i + 1, j, k), nid(i + 1, j + 1, k), nid(i, j + 1, k),
                         nid(i, j, k + 1), nid(i + 1, j, k + 1), nid(i + 1, j + 1, k + 1), nid(i, j + 1, k + 1)]
                    if flip == 0:
                        n = n[4:] + n[:4]
                    flip -= 1
                    eid += r.randint(1, 3)  # ids with gaps, as pre-processors leave them
                    f.write("%8d%8d" % (eid, 7) + "".join("%8d" % x for x in n) + "\n")
        f.write("*END\n")


def part(r, name, z0, directory, index):
    """A part in the slab z0 .. z0 + height (mm); returns (yaml lines, height, is_cloud, top face selector)."""
    kind = r.choice(["box", "box", "cylinder", "projectile", "tube", "keyword", "cloud", "cloud-cylinder"])
    h = r.choice([1.0, 1.5, 2.0, 2.5])
    n = [r.randint(1, 4), r.randint(1, 4), r.randint(1, 6)]
    cloud = kind.startswith("cloud")
    if kind == "box":
        gen = "{type: box, origin: [0, 0, %s], size: [%s, %s, %s], element_size: %s}" % (
            mm(z0), mm(n[0] * h), mm(n[1] * h), mm(n[2] * h), mm(h))
        height = n[2] * h
    elif kind == "cylinder":
        rad, height = r.uniform(2, 6), r.uniform(2, 8)
        gen = "{type: cylinder, origin: [0, 0, %s], radius: %s, height: %s, element_size: %s, core: %s}" % (
            mm(z0), mm(rad), mm(height), mm(max(h, rad / 3)), r.choice(["butterfly", "ogrid"]))
    elif kind == "projectile":
        rad, height = r.uniform(2, 5), r.uniform(4, 10)
        # origin is the nose centre, the body along +z from it
        gen = "{type: projectile, origin: [0, 0, %s], radius: %s, length: %s, element_size: %s}" % (
            mm(z0), mm(rad), mm(height), mm(max(h, rad / 2.5)))
    elif kind == "tube":
        ro = r.uniform(3, 8)
        height = r.uniform(2, 8)
        gen = "{type: cylinder, origin: [0, 0, %s], inner_radius: %s, radius: %s, height: %s, element_size: %s}" % (
            mm(z0), mm(ro * r.uniform(0.5, 0.9)), mm(ro), mm(height), mm(max(h, ro / 4)))
    elif kind == "keyword":
        f = os.path.join(directory, "mesh%d.k" % index)
        keyword_mesh(r, f, n[0], n[1], n[2], h, z0)
        gen = "{type: keyword, file: %s, unit: mm}" % os.path.basename(f)
        height = n[2] * h
    elif kind == "cloud":
        gen = "{type: cloud, origin: [0, 0, %s], size: [%s, %s, %s], spacing: %s, jitter: %.2f, seed: %d}" % (
            mm(z0), mm(n[0] * h + h), mm(n[1] * h + h), mm(n[2] * h + h), mm(h), r.uniform(0, 0.4), r.randint(1, 99))
        height = n[2] * h + h
    else:
        rad, height = r.uniform(2, 5), r.uniform(3, 8)
        gen = "{type: cloud, body: cylinder, origin: [0, 0, %s], radius: %s, height: %s, spacing: %s, jitter: %.2f}" % (
            mm(z0), mm(rad), mm(height), mm(max(h, rad / 3)), r.uniform(0, 0.4))
    form = "rkpm" if cloud else r.choice(FORMULATIONS)
    top = {"projectile": "{type: named, name: tail}",
           "keyword": "{type: plane, point: [0, 0, %s], normal: [0, 0, 1], tolerance: 1e-6}" % mm(z0 + height)}.get(
               kind, "{type: named, name: top}")
    lines = ["  %s:" % name, "    generator: %s" % gen, "    material: %s" % material(r), "    formulation: %s" % form]
    if form == "fem-1pt" and r.random() < 0.7:
        lines.append("    hourglass: {type: %s, coefficient: %.3f}" % (
            r.choice(["viscous", "stiffness", "viscous-plain", "none"]), r.uniform(0.01, 0.15)))
    converts = form == "fem-nodal" and not cloud and r.random() < 0.25
    if form in ("fem-nodal", "rkpm"):
        schemes = ["scni", "sd-scni", "dni"] if form == "rkpm" else ["scni", "sd-scni"]
        stabs = ["nsni", "mscni", "none"] if form == "rkpm" else ["mscni", "none"]
        if r.random() < 0.6:
            scheme = "scni" if converts else r.choice(schemes)  # the stabilizations are of scni; coupled parts scni
            lines.append("    nodal_integration: {scheme: %s, stabilization: %s}" % (
                scheme, r.choice(stabs) if scheme == "scni" else "none"))
    if form == "rkpm" and r.random() < 0.6:
        support = r.choice(["box", "sphere"])
        lo = 1.3 if support == "box" else 1.5
        a = round(r.uniform(lo, 2.5), 2)
        lines.append("    rk: {support: %s, normalized_support: %.2f}" % (support, a if a != int(a) else a + 0.01))
    if form in ("fem-1pt", "fem-2x2x2") and r.random() < 0.3:
        lines.append("    erosion: {%s}" % r.choice(["principal_strain: 0.3", "volumetric_strain: 0.3", "time_step: 1 ns"]))
    if converts:
        lines.append("    conversion: {principal_strain: %.3f}" % r.uniform(0.001, 0.05))
    if r.random() < 0.5:
        lines.append("    initial_velocity: [0, 0, %s]" % ("%.3g m/s" % r.uniform(-200, 200)))
    return lines, height, cloud, top


def deck(r, directory):
    nparts = r.choice([1, 1, 2, 2, 3])
    lines = ["title: model fuzz", "time: {end: %s, output_interval: %s, max_steps: %d}" % (
        "%.3g us" % r.uniform(0.5, 5), "%.3g us" % r.uniform(0.1, 2), r.randint(1, 8)), "parts:"]
    z, names, meshed = 0.0, [], []
    for i in range(nparts):
        name = "p%d" % i
        pl, height, cloud, top_face = part(r, name, z, directory, i)
        lines += pl
        names.append(name)
        if not cloud:
            meshed.append(name)
        z = round(z + height + r.uniform(0.1, 1.0), 2)  # a gap; positions in whole 10 um
    lines += ["node_sets:", "  base: {part: p0, select: {type: plane, point: [0, 0, 0], normal: [0, 0, 1], tolerance: 1e-6}}"]
    bc = r.choice(["fixed", "velocity", "rollers", None])
    if bc:
        lines.append("boundary_conditions:")
        lines.append({"fixed": "  - {node_set: base, fixed: all}",
                      "velocity": "  - {node_set: base, velocity: {z: %.3g m/s}}" % r.uniform(-50, 50),
                      "rollers": "  - {node_set: base, fixed: [z]}"}[bc])
    top = names[-1]
    if r.random() < 0.4:
        lines += ["face_sets:", "  loaded: {part: %s, select: %s}" % (top, top_face),
                  "loads:", "  - {type: pressure, face_set: loaded, pressure: {triangular: {peak: %d MPa, duration: 2 us}}}"
                  % r.randint(1, 500)]
    elif r.random() < 0.3:
        lines += ["loads:", "  - {type: nodal_force, node_set: base, force: {z: %d N}, total: true}" % r.randint(-1000, 1000)]
    contacts = []
    if len(meshed) >= 2 and r.random() < 0.7:
        kind = r.choice(["surface-to-surface", "surface-to-surface", "single-surface"])
        extra = ", formulation: mortar" if kind == "surface-to-surface" and r.random() < 0.3 else ""
        fr = ", friction: {static: 0.3, dynamic: 0.2}" if r.random() < 0.3 else ""
        contacts.append("  - {type: %s, surfaces: [%s, %s]%s%s}" % (kind, meshed[0], meshed[1], extra, fr))
    if meshed and r.random() < 0.3:
        contacts.append("  - {type: rigid-wall, surfaces: [%s], point: [0, 0, %s], normal: [0, 0, -1]}" % (
            meshed[-1], mm(z + 1)))
    if contacts:
        lines += ["contacts:"] + contacts
    return "\n".join(lines) + "\n"


FAILURE_MARKS = ("AddressSanitizer", "runtime error:", "LeakSanitizer", "internal error", "Segmentation")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("rkfem")
    ap.add_argument("--inputs", type=int, default=40)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--seconds", type=float, default=0, help="run inputs until this many seconds have passed")
    ap.add_argument("--timeout", type=float, default=120)
    ap.add_argument("--keep", default="build/model_fuzz_failures")
    a = ap.parse_args()
    env = dict(os.environ, OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "2"),
               ASAN_OPTIONS="detect_leaks=0:abort_on_error=0:exitcode=99",
               UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:exitcode=98")
    counts = {"done": 0, "refused": 0, "unstable": 0, "failed": 0}
    start = time.time()
    i = 0
    while (a.seconds > 0 and time.time() - start < a.seconds) or (a.seconds <= 0 and i < a.inputs):
        seed = a.seed * 1000003 + i
        i += 1
        r = random.Random(seed)
        work = tempfile.mkdtemp(prefix="rkfem_model_fuzz_")
        text = deck(r, work)
        path = os.path.join(work, "deck.yaml")
        with open(path, "w") as f:
            f.write(text)
        verdict, detail = None, ""
        for args in (["check", path], ["run", path, "--out", os.path.join(work, "out"), "--quiet"]):
            try:
                p = subprocess.run([a.rkfem] + args, capture_output=True, text=True, timeout=a.timeout, env=env)
                out, code = p.stdout + p.stderr, p.returncode
            except subprocess.TimeoutExpired:
                out, code = "timed out after %g s" % a.timeout, -1
            bad = code not in (0, 2, 3) or any(m in out for m in FAILURE_MARKS)
            if bad:
                verdict, detail = "failed", "%s exit %d: %s" % (args[0], code, out.strip().splitlines()[-1:] or "")
                break
            if code == 2:
                verdict, detail = "refused", out.strip()
                break
            if args[0] == "run":
                verdict = "unstable" if code == 3 else "done"
        counts[verdict] += 1
        if verdict == "failed":
            keep = os.path.join(a.keep, "seed%d" % seed)
            shutil.rmtree(keep, ignore_errors=True)
            shutil.copytree(work, keep, ignore=shutil.ignore_patterns("out"))
            print("model-fuzz: seed %d failed (%s); deck kept in %s" % (seed, detail, keep), flush=True)
        elif verdict == "refused" and os.environ.get("MODEL_FUZZ_VERBOSE"):
            print("model-fuzz: seed %d refused: %s" % (seed, detail), flush=True)
        shutil.rmtree(work, ignore_errors=True)
    print("model-fuzz: %d inputs in %.0f s: %d done, %d unstable (exit 3), %d refused (exit 2), %d failed" % (
        i, time.time() - start, counts["done"], counts["unstable"], counts["refused"], counts["failed"]), flush=True)
    return 1 if counts["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
