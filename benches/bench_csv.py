"""CSV load throughput: a 384,000-row x 6-column file (time + 5 channels, 17 significant digits).

    python benches/bench_csv.py [--rows 384000] [--repeat 5]

Work: ``rotorid.io.load_recording`` (layout detection, pandas' C parser, time-column check,
unit conversion, NaN and clipping checks, Recording) against a bare ``pandas.read_csv`` of the
same file, best of ``repeat`` each (interleaved). Two layouts: a plain comma-separated file with a header, and
the same data as a DAQ exports it (preamble with the sample rate, ``;`` separator, decimal
comma, units in parentheses, six channels and no time column), read by pandas with the options spelled out.
The target is a ratio below 1.5.
"""

import argparse
import os
import sys
import tempfile
import warnings

import numpy as np
import pandas as pd

sys.path.insert(0, os.path.dirname(__file__))
from common import best_of  # noqa: E402

from rotorid.io import load_recording  # noqa: E402

FS = 10240.0
CHANNELS = ["x1", "y1", "x2", "y2", "force"]  # plain file: time + these
DAQ_UNITS = {"x1": "mm", "y1": "mm", "x2": "mm", "y2": "mm", "force": "N", "kp": "V"}  # DAQ file: no time column


def make_table(rows):
    rng = np.random.default_rng(3)
    t = np.arange(rows) / FS
    cols = [40e-6 * np.sin(2 * np.pi * 30 * t + i) + 2e-7 * rng.standard_normal(rows) for i in range(4)]
    cols.append(10.0 * rng.standard_normal(rows))
    cols.append(np.where(np.arange(rows) % 341 < 5, 5.0, 0.0))
    return t, np.column_stack(cols)


def write_plain(path, t, data):
    with open(path, "w") as fh:
        fh.write("time [s]," + ",".join(f"{c} [{'N' if c == 'force' else 'm'}]" for c in CHANNELS) + "\n")
        np.savetxt(fh, np.column_stack([t, data[:, :len(CHANNELS)]]), fmt="%.17g", delimiter=",")


def write_daq(path, data):
    """Preamble, ';' separator, decimal comma, units in parentheses, no time column."""
    with open(path, "w") as fh:
        fh.write("DAQ 9000 export\nDate: 2024-05-01 10:00:00\nSample rate: 10240 Hz\nComment: bench\n\n")
        fh.write(";".join(f"{c} ({unit})" for c, unit in DAQ_UNITS.items()) + "\n")
        scaled = data * np.array([1e3, 1e3, 1e3, 1e3, 1.0, 1.0])
        body = pd.DataFrame(scaled).to_csv(sep=";", decimal=",", header=False, index=False, float_format="%.10g")
        fh.write(body)
    return 5  # preamble lines (pandas' skiprows; the header follows)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=384_000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    t, data = make_table(args.rows)
    with tempfile.TemporaryDirectory() as tmp:
        plain = os.path.join(tmp, "plain.csv")
        daq = os.path.join(tmp, "daq.csv")
        write_plain(plain, t, data)
        skip = write_daq(daq, data)
        cases = [
            ("plain CSV", plain, lambda: pd.read_csv(plain)),
            ("DAQ export (preamble, ';', decimal ',')", daq,
             lambda: pd.read_csv(daq, sep=";", decimal=",", skiprows=skip)),
        ]
        print(f"{args.rows} rows x 6 columns, best of {args.repeat}")
        for label, path, baseline in cases:
            size = os.path.getsize(path) / 2**20
            rec = load_recording(path)
            assert rec.n_samples == args.rows and rec.fs_hz == FS, (rec.n_samples, rec.fs_hz)
            # interleaved, so that a load from elsewhere on the machine hits both alike
            t_load = t_pd = float("inf")
            for _ in range(args.repeat):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    t_load = min(t_load, best_of(lambda: load_recording(path), repeat=1, warmup=0))
                t_pd = min(t_pd, best_of(baseline, repeat=1, warmup=0))
            print(f"  {label} ({size:.1f} MiB):")
            print(f"    rotorid.io.load_recording  {t_load * 1e3:8.1f} ms")
            print(f"    pandas.read_csv            {t_pd * 1e3:8.1f} ms")
            print(f"    ratio                      {t_load / t_pd:8.2f}")


if __name__ == "__main__":
    main()
