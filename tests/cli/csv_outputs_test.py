#!/usr/bin/env python3
"""Every CSV output of stagefit loads with the default options of Python's csv module (and of numpy's
genfromtxt(names=True) and pandas' read_csv where they are installed): the header is the first line,
every row has one field per column, the numeric columns parse as numbers, and the units are in the
"<stem>.meta.json" sidecar (docs/csv-outputs.md).

Usage: csv_outputs_test.py STAGEFIT SOURCE_DIR
"""
import csv
import glob
import json
import os
import subprocess
import sys
import tempfile

stagefit, source = sys.argv[1], sys.argv[2]
m = os.path.join(source, "measurements")
failures = []


def run(*args):
    r = subprocess.run([stagefit, *args], capture_output=True, text=True)
    if r.returncode not in (0, 3):
        failures.append("stagefit %s: exit %d\n%s%s" % (" ".join(args), r.returncode, r.stdout, r.stderr))


def is_number(text):
    try:
        float(text)
        return True
    except ValueError:
        return False


with tempfile.TemporaryDirectory() as d:
    run("frf", "--io", "compliance", "--points", "50", "--out", os.path.join(d, "frf_compliance.csv"))
    run("frf", "--io", "raw", "--measurement", os.path.join(m, "microstation-12x10", "frf.mat"),
        "--out", os.path.join(d, "frf_at_measurement.csv"))
    run("estimate", os.path.join(m, "microstation-12x10", "raw.mat"), "--out", os.path.join(d, "estimate.csv"))
    run("synthesize", "--points", "40", "--out", os.path.join(d, "synthesized.csv"))
    run("compare", "--measurement", os.path.join(m, "microstation-12x10", "frf.mat"), "--out-dir", os.path.join(d, "compare"))
    run("export", "--out", os.path.join(d, "ss.csv"))
    run("simulate", "tomography", "--duration", "1 s", "--rate", "1 kHz", "--out-dir", os.path.join(d, "simulate"))
    run("simulate", "raster", "--duration", "1 s", "--rate", "1 kHz", "--out-dir", os.path.join(d, "simulate"))
    dist = os.path.join(m, "disturbance")
    run("disturbance", "psd", os.path.join(dist, "spindle_60rpm.csv"), "--kind", "spindle",
        "--out", os.path.join(d, "spindle_psd.csv"))
    run("disturbance", "sensitivity", "--source", "rz.F.Dz", "--output", "X_rel.Dz", "--at",
        os.path.join(d, "spindle_psd.csv"), "--out", os.path.join(d, "rz_sensitivity.csv"))
    run("disturbance", "force", "--psd", os.path.join(d, "spindle_psd.csv"), "--column", "Dz", "--sensitivity",
        os.path.join(d, "rz_sensitivity.csv"), "--out", os.path.join(d, "rz_force_psd.csv"))
    run("disturbance", "synth", "--psd", os.path.join(d, "rz_force_psd.csv"), "--duration", "2 s", "--rate", "1 kHz",
        "--out", os.path.join(d, "rz_force_signal.csv"))

    files = sorted(glob.glob(os.path.join(d, "**", "*.csv"), recursive=True))
    expected = ["frf_compliance.csv", "frf_at_measurement.csv", "estimate.csv", "synthesized.csv", "compare_frf.csv",
                "ss_A.csv", "tomography.csv", "tomography_psd.csv", "raster.csv", "spindle_psd.csv",
                "rz_sensitivity.csv", "rz_force_psd.csv", "rz_force_signal.csv"]
    names = [os.path.basename(f) for f in files]
    for e in expected:
        if e not in names:
            failures.append("no output %s (written: %s)" % (e, ", ".join(names)))

    try:
        import numpy
    except ImportError:
        numpy = None
    try:
        import pandas
    except ImportError:
        pandas = None

    checked = 0
    for path in files:
        name = os.path.relpath(path, d)
        with open(path, newline="") as f:
            first = f.readline()
        if first.startswith("#"):
            failures.append("%s: the first line is a comment, not the header: %r" % (name, first))
            continue
        with open(path, newline="") as f:
            reader = csv.DictReader(f)
            header = reader.fieldnames or []
            rows = list(reader)
        if not header or any(not h for h in header) or len(set(header)) != len(header):
            failures.append("%s: header %r: expected distinct non-empty column names" % (name, header))
            continue
        if not rows:
            failures.append("%s: no data rows" % name)
            continue
        bad = [r for r in rows if None in r or any(v is None for v in r.values())]
        if bad:
            failures.append("%s: %d rows whose field count differs from the header's" % (name, len(bad)))
            continue
        # A column is numeric when its first row is; then every row's value must be a number (or empty).
        # A column is numeric when its first non-empty value is; every other value must then be a number or
        # empty (a geometry sidecar leaves a channel's numbers empty when its geometry is unknown).
        numeric = []
        for h in header:
            values = [r[h] for r in rows if r[h] != ""]
            if values and is_number(values[0]):
                numeric.append(h)
        if not numeric and not name.endswith(".geometry.csv"):
            failures.append("%s: no numeric column" % name)
        for h in numeric:
            wrong = [r[h] for r in rows if r[h] != "" and not is_number(r[h])]
            if wrong:
                failures.append("%s: column %s: %r is not a number" % (name, h, wrong[0]))
        if not name.endswith(".geometry.csv"):
            meta = path[:-4] + ".meta.json"
            if not os.path.exists(meta):
                failures.append("%s: no sidecar %s" % (name, os.path.basename(meta)))
            else:
                with open(meta) as f:
                    j = json.load(f)
                units = j.get("units", {})
                unknown = [c for c in units if c not in header]
                if unknown:
                    failures.append("%s: the sidecar names units of columns it does not have: %s" % (name, unknown))
        if numpy is not None:
            data = numpy.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding="utf-8")
            if len(data.dtype.names) != len(header) or data.shape[0] != len(rows):
                failures.append("%s: numpy.genfromtxt(names=True) read %d columns x %d rows, expected %d x %d"
                                % (name, len(data.dtype.names), data.shape[0], len(header), len(rows)))
        if pandas is not None:
            frame = pandas.read_csv(path)
            if list(frame.columns) != header or len(frame) != len(rows):
                failures.append("%s: pandas.read_csv read columns %s, %d rows" % (name, list(frame.columns), len(frame)))
        checked += 1

print("checked %d CSV outputs (numpy: %s, pandas: %s)" % (checked, numpy is not None, pandas is not None))
if failures:
    print("\n".join(failures))
    sys.exit(1)
