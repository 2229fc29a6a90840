"""Run a snippet in fresh interpreters with ``RAYON_NUM_THREADS`` set (the pool's size is fixed
when the core is first loaded), for tests that a result does not depend on the thread count."""

import os
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def outputs_on_threads(code, threads=("1", "2"), timeout=300):
    """The array each run of ``code`` saves to ``sys.argv[1]`` (``np.save``), one per thread count,
    run from the repository's root."""
    outs = []
    with tempfile.TemporaryDirectory() as d:
        for n in threads:
            path = os.path.join(d, f"{n}.npy")
            env = {**os.environ, "RAYON_NUM_THREADS": n}
            r = subprocess.run([sys.executable, "-c", code, path], env=env, capture_output=True, text=True,
                               timeout=timeout, cwd=ROOT)
            assert r.returncode == 0, r.stderr[-2000:]
            outs.append(np.load(path))
    return outs
