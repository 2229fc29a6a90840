"""Command line: ``rotorid demo --out DIR`` runs the report's numerical experiments on the NSF rig."""

from __future__ import annotations

import argparse
import sys


def main(argv=None):
    ap = argparse.ArgumentParser(prog="rotorid", description="Bearing coefficient identification for rigid rotors")
    sub = ap.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("demo", help="run the report's numerical experiments on the built-in NSF rig")
    d.add_argument("--out", default="rotorid_demo", help="output directory for PNG figures and CSV tables")
    d.add_argument("--step-rpm", type=float, default=50.0, help="speed step of the imbalance sweep (rpm)")
    d.add_argument("--amplitude-resolution-um", type=float, default=None,
                   help="1X amplitude resolution of the measurement model (µm; default 0.0254 = 0.001 mil)")
    d.add_argument("--phase-resolution-deg", type=float, default=None, help="1X phase resolution (deg)")
    d.add_argument("--noise-um", type=float, default=0.0, help="added complex Gaussian noise (µm rms)")
    args = ap.parse_args(argv)
    if args.cmd == "demo":
        from . import demo
        from .simulate import ProbeResolution

        base = ProbeResolution()
        res = ProbeResolution(
            amplitude_m=base.amplitude_m if args.amplitude_resolution_um is None else args.amplitude_resolution_um * 1e-6,
            phase_deg=base.phase_deg if args.phase_resolution_deg is None else args.phase_resolution_deg,
            noise_m=args.noise_um * 1e-6)
        out = demo.synchronous(args.out, step_rpm=args.step_rpm, resolution=res)
        imp = demo.impact(args.out)
        print(f"wrote {len(out['files']) + len(imp['files'])} files to {args.out}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
