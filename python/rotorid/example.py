"""The bundled example data set: simulated raw recordings of the example rig in lab form.

``rotorid example --out DIR`` copies it; ``python -m rotorid.example DIR`` regenerates it
(deterministic). Contents (TDMS files, float32, lab channel names, mils / lbf, 5 kHz):

    imbalance/run_S0.tdms ... run_C90.tdms   four added-imbalance runs: 5 g static and couple sets
                                             at 0 and 90 deg, dwells of 2 s at 3000-6000 rpm
    imbalance/baseline.tdms                  the same dwells without added mass
    imbalance/slow_roll.tdms                 2 s at 400 rpm (run-out)
    impact/impact_x.tdms, impact_y.tdms      five 4 kN, 2 ms impacts at the CG at 2000 rpm
    imbalance.toml, impact.toml              configs for `rotorid identify`
    truth.toml                               the bearing coefficients used to simulate
    pedestal/                                the same rig on flexible pedestals (example_pedestals):
                                             runs S0, C0 and a baseline, impacts x and y, with
                                             housing accelerometers (g) and their truth.toml
    pedestal_imbalance.toml, pedestal_impact.toml   configs with [pedestals] measured = true

All recordings carry probe noise 0.5 µm rms, run-out (8, 3, 1 µm at 1X, 2X, 3X), a remnant
imbalance (1.0 g and 0.6 g) and probes away from the bearings (s1 = 0.119, s2 = 0.146 m).
"""

from __future__ import annotations

import os
import shutil
import sys

import numpy as np

from .model import Imbalance

HERE = os.path.join(os.path.dirname(__file__), "data", "example")
LAB_NAMES = {"x1": "Prox DE X", "y1": "Prox DE Y", "x2": "Prox FE X", "y2": "Prox FE Y", "kp": "Keyphasor",
             "force": "Hammer"}
LAB_UNITS = {"x1": "mil", "y1": "mil", "x2": "mil", "y2": "mil", "kp": "V", "force": "lbf"}
ACC_NAMES = {"px1": "Acc DE X", "py1": "Acc DE Y", "px2": "Acc FE X", "py2": "Acc FE Y"}
SETS = {"S0": ((5.0, 5.0), (0.0, 0.0)), "C0": ((5.0, 5.0), (0.0, 180.0)),
        "S90": ((5.0, 5.0), (90.0, 90.0)), "C90": ((5.0, 5.0), (90.0, 270.0))}
SPEEDS = [3000.0, 4000.0, 5000.0, 6000.0]
FS = 5000.0

_CHANNELS_TOML = "\n".join(
    f'"{LAB_NAMES[k]}" = {{ to = "{k}", unit = "{LAB_UNITS[k]}" }}' for k in ("x1", "y1", "x2", "y2", "kp", "force"))


def path() -> str:
    return HERE


def copy_example(out: str, *, overwrite: bool = False) -> str:
    """Copy the bundled example data set to ``out``; files already there are replaced only with
    ``overwrite``."""
    from ._validate import flag
    from ._validate import path as _path
    from .errors import RotoridError

    _path("out", out)
    overwrite = flag("overwrite", overwrite)
    if not os.path.isdir(HERE):
        raise RotoridError(f"the bundled example data set is missing from {HERE}")
    if os.path.exists(out) and not os.path.isdir(out):
        raise RotoridError(f"{out} is a file; choose another --out")
    if not overwrite and os.path.isdir(out):
        clash = [os.path.relpath(os.path.join(d, f), HERE) for d, _, fs in os.walk(HERE) for f in fs
                 if os.path.exists(os.path.join(out, os.path.relpath(os.path.join(d, f), HERE)))]
        if clash:
            raise RotoridError(f"{out} already holds {len(clash)} file(s) of the example ({', '.join(sorted(clash)[:3])}"
                               f"{' ...' if len(clash) > 3 else ''}); pass --overwrite to replace them")
    try:
        shutil.copytree(HERE, out, dirs_exist_ok=True)
    except OSError as exc:
        raise RotoridError(f"cannot write the example to {out}: {exc}") from None
    return out


def generate(out: str = HERE) -> str:
    """(Re)create the example data set in ``out``."""
    from . import rawsim
    from .io import save_tdms

    rotor, brg, remnant = rawsim.example_rig()
    os.makedirs(os.path.join(out, "imbalance"), exist_ok=True)
    os.makedirs(os.path.join(out, "impact"), exist_ok=True)

    def save(rec, rel):
        save_tdms(rec, os.path.join(out, rel), group="DAQ", names=LAB_NAMES, units=LAB_UNITS, dtype="float32")

    for i, (name, (mass_g, ang)) in enumerate(SETS.items()):
        imb = Imbalance(tuple(m * 1e-3 for m in mass_g), ang, name=name)
        save(rawsim.imbalance_recording(rotor, brg, speeds_rpm=SPEEDS, added=imb, remnant=remnant, dwell_s=2.0,
                                        fs_hz=FS, seed=101 + i), f"imbalance/run_{name}.tdms")
    save(rawsim.imbalance_recording(rotor, brg, speeds_rpm=SPEEDS, added=None, remnant=remnant, dwell_s=2.0, fs_hz=FS,
                                    seed=201, kind="baseline"), "imbalance/baseline.tdms")
    save(rawsim.imbalance_recording(rotor, brg, speeds_rpm=[400.0], added=None, remnant=remnant, dwell_s=2.0, fs_hz=FS,
                                    seed=202, kind="slow_roll"), "imbalance/slow_roll.tdms")
    for i, d in enumerate("xy"):
        save(rawsim.impact_recording(rotor, brg, speed_rpm=2000.0, plane=0.0, direction=d, remnant=remnant, fs_hz=FS,
                                     seed=301 + i), f"impact/impact_{d}.tdms")
    runs = "\n".join(f'[[imbalance.runs]]\nfile = "imbalance/run_{n}.tdms"\nname = "{n}"\nmass_g = [{m[0]}, {m[1]}]\n'
                     f'angle_deg = [{a[0]}, {a[1]}]\n' for n, (m, a) in SETS.items())
    head = ('# rotorid example: the NSF rotor on two different, cross-coupled bearings (truth.toml)\n'
            '[rig]\nbuiltin = "nsf"\n\n[channels]\n' + _CHANNELS_TOML + "\n\n")
    with open(os.path.join(out, "imbalance.toml"), "w") as fh:
        fh.write(head + '[imbalance]\nbaseline = "imbalance/baseline.tdms"\nslow_roll = "imbalance/slow_roll.tdms"\n'
                 'steady = true\n\n' + runs + '\n[output]\ndir = "out_imbalance"\nunits = "SI"\n')
    with open(os.path.join(out, "impact.toml"), "w") as fh:
        fh.write(head + '[impact]\nband_hz = [5.0, 150.0]\nrecord_s = 0.25\n'
                 'kcm_band_hz = [20.0, 120.0]        # K, C and apparent mass fitted over this band -> kcm_fit.csv\n\n'
                 '[[impact.tests]]\nfile = "impact/impact_x.tdms"\nplane_m = 0.0\ndirection = "x"\n\n'
                 '[[impact.tests]]\nfile = "impact/impact_y.tdms"\nplane_m = 0.0\ndirection = "y"\n\n'
                 '[output]\ndir = "out_impact"\nunits = "SI"\n')
    _generate_pedestal(out, rotor, brg, remnant, head)
    with open(os.path.join(out, "truth.toml"), "w") as fh:
        fh.write("# bearing coefficients used to simulate the example, k[bearing][i][j] (N/m), c (N*s/m)\n")
        fh.write(f"k = {brg.k.tolist()}\nc = {brg.c.tolist()}\n")
        fh.write(f"remnant_mass_g = {[m * 1e3 for m in remnant.mass_kg]}\nremnant_angle_deg = {list(remnant.angle_deg)}\n")
    return out


def _generate_pedestal(out, rotor, brg, remnant, head):
    """The pedestal part of the example: the rig on example_pedestals(), accelerometers in g."""
    from . import rawsim
    from .io import save_tdms
    from .pedestal import example_pedestals

    ped = example_pedestals()
    os.makedirs(os.path.join(out, "pedestal"), exist_ok=True)
    names = LAB_NAMES | ACC_NAMES
    units = LAB_UNITS | {k: "g" for k in ACC_NAMES}

    def save(rec, rel):
        save_tdms(rec, os.path.join(out, rel), group="DAQ", names=names, units=units, dtype="float32")

    sets = {k: SETS[k] for k in ("S0", "C0")}
    for i, (name, (mass_g, ang)) in enumerate(sets.items()):
        imb = Imbalance(tuple(m * 1e-3 for m in mass_g), ang, name=name)
        save(rawsim.imbalance_recording(rotor, brg, speeds_rpm=SPEEDS, added=imb, remnant=remnant, dwell_s=2.0,
                                        fs_hz=FS, seed=401 + i, pedestals=ped), f"pedestal/run_{name}.tdms")
    save(rawsim.imbalance_recording(rotor, brg, speeds_rpm=SPEEDS, added=None, remnant=remnant, dwell_s=2.0, fs_hz=FS,
                                    seed=501, kind="baseline", pedestals=ped), "pedestal/baseline.tdms")
    for i, d in enumerate("xy"):
        save(rawsim.impact_recording(rotor, brg, speed_rpm=2000.0, plane=0.0, direction=d, remnant=remnant, fs_hz=FS,
                                     seed=601 + i, pedestals=ped), f"pedestal/impact_{d}.tdms")
    chans = "\n".join(f'"{v}" = {{ to = "{k}", unit = "g" }}' for k, v in ACC_NAMES.items())
    hd = head.replace("[channels]\n", "[channels]\n" + chans + "\n").replace(
        "# rotorid example: the NSF rotor", "# rotorid example: flexible pedestals under the NSF rotor")
    ped_sec = "[pedestals]\nmeasured = true\nidentify = true\n\n"
    runs = "\n".join(f'[[imbalance.runs]]\nfile = "pedestal/run_{n}.tdms"\nname = "{n}"\nmass_g = [{m[0]}, {m[1]}]\n'
                     f'angle_deg = [{a[0]}, {a[1]}]\n' for n, (m, a) in sets.items())
    with open(os.path.join(out, "pedestal_imbalance.toml"), "w") as fh:
        fh.write(hd + ped_sec + '[imbalance]\nbaseline = "pedestal/baseline.tdms"\nsteady = true\n\n' + runs
                 + '\n[output]\ndir = "out_pedestal_imbalance"\nunits = "SI"\n')
    with open(os.path.join(out, "pedestal_impact.toml"), "w") as fh:
        fh.write(hd + ped_sec + '[impact]\nband_hz = [5.0, 150.0]\nrecord_s = 0.25\n\n'
                 '[[impact.tests]]\nfile = "pedestal/impact_x.tdms"\nplane_m = 0.0\ndirection = "x"\n\n'
                 '[[impact.tests]]\nfile = "pedestal/impact_y.tdms"\nplane_m = 0.0\ndirection = "y"\n\n'
                 '[output]\ndir = "out_pedestal_impact"\nunits = "SI"\n')
    with open(os.path.join(out, "pedestal", "truth.toml"), "w") as fh:
        fh.write("# pedestals used to simulate (rotorid.example_pedestals()); bearings as ../truth.toml\n")
        fh.write(f"mass_kg = {ped.mass_kg.tolist()}\nk = {ped.k.tolist()}\nc = {ped.c.tolist()}\n")


def truth():
    import tomllib

    with open(os.path.join(HERE, "truth.toml"), "rb") as fh:
        t = tomllib.load(fh)
    from .model import BearingCoefficients

    return BearingCoefficients(np.array(t["k"]), np.array(t["c"]))


if __name__ == "__main__":
    print(generate(sys.argv[1] if len(sys.argv) > 1 else HERE))
