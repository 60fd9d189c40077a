"""Resistance of a static plug under gas-grid refinement, for each face-permeability rule.

A uniform plug (solid fraction 0.55, length 2 or 3 cm, three offsets against the grid) is
deposited with the tent weights of eq. (7) as a continuum would be, and the steady pressure drop of
eq. (5) across it at v_s = 1 m/s is compared with its true Darcy resistance eta v_s L_p /
kappa(phi_p). The ratio tells how much of the plug's resistance the discretisation keeps: both
rules converge to 1 (first order in the node spacing); at the papers' 150 nodes the harmonic rule
keeps more. Static: the grains' response (slower plugs where the resistance is kept) is the
identification study's (config/identification.yaml).

    python benchmarks/studies/face_rule_refinement.py [--nodes 75 150 300 600 1200] [--out DIR]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from engine import gas
from engine.case import KEYS, Case

LENGTH, GRAIN, VISCOSITY, VS = 0.525, 1.4e-3, 6.73e-5, 1.0
SOLID_FRACTION, PLUG_START = 0.55, 0.25
PLUG_LENGTHS = (0.02, 0.03)
OFFSETS = (0.0, 0.37, 0.71)  # plug start past a node, fraction of the node spacing


def carman_kozeny(phi: float) -> float:
    """Eq. (4), m2."""
    return GRAIN**2 * phi**3 / (180 * (1 - phi) ** 2)


def tent_fraction(a: float, b: float, x: np.ndarray, h: float) -> np.ndarray:
    """Share of each node's tent (eq. 7, unit area) covering [a, b] (a, b away from the tube ends)."""
    def cumulative(t):  # integral of the unit-area tent from -h to t
        t = np.clip(t, -h, h)
        return np.where(t < 0, (t + h) ** 2 / (2 * h * h), 1 - (h - t) ** 2 / (2 * h * h))
    return cumulative(b - x) - cumulative(a - x)


def plug_drop(nodes_x: int, face: str, plug_length: float, offset: float) -> float:
    """Steady pressure drop (Pa) of the tube holding one deposited plug."""
    field = gas.GasField(Case({"tube": {"length": LENGTH}, "particles": {"diameter": GRAIN},
                               "gas": {"viscosity": VISCOSITY, "superficial_velocity": VS, "nodes_x": nodes_x,
                                       "nodes_y": 2, "nodes_z": 2, "face_permeability": face}}))
    h = LENGTH / nodes_x
    start = PLUG_START + offset * h
    solid = SOLID_FRACTION * tent_fraction(start, start + plug_length, field.x, h)
    field.set_solid_fraction(np.broadcast_to(solid[:, None, None], field.nodes).copy())
    for _ in range(30):  # backward Euler with 10 s steps: the steady state to round-off
        field.step(10.0)
    return field.pressure_drop()


def table(nodes=(75, 150, 300, 600, 1200)) -> pd.DataFrame:
    """One row per (rule, plug length, offset, nodes): drop and its ratio to the true resistance."""
    rows = []
    for face in KEYS["gas.face_permeability"].choices:
        for plug_length in PLUG_LENGTHS:
            exact = VISCOSITY * VS * plug_length / carman_kozeny(1 - SOLID_FRACTION)
            for offset in OFFSETS:
                for nx in nodes:
                    drop = plug_drop(nx, face, plug_length, offset)
                    rows.append({"face": face, "plug_length_m": plug_length, "offset": offset,
                                 "nodes_x": nx, "spacing_mm": 1e3 * LENGTH / nx,
                                 "pressure_drop_Pa": drop, "kept": drop / exact})
    return pd.DataFrame(rows)


def markdown(df: pd.DataFrame) -> str:
    """Range of the kept resistance over plug lengths and offsets, per rule and grid."""
    summary = df.groupby(["face", "nodes_x", "spacing_mm"])["kept"].agg(["min", "max"]).reset_index()
    lines = ["| face rule | nodes | spacing (mm) | resistance kept (min–max) |", "|---|---|---|---|"]
    for _, r in summary.iterrows():
        lines.append(f"| {r['face']} | {r['nodes_x']} | {r['spacing_mm']:.2f} | {r['min']:.2f}–{r['max']:.2f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--nodes", type=int, nargs="+", default=[75, 150, 300, 600, 1200])
    parser.add_argument("--out", type=Path, default=None, help="folder for face_rule_refinement.{csv,md}")
    args = parser.parse_args(argv)
    df = table(args.nodes)
    text = markdown(df)
    print(text)
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        df.to_csv(args.out / "face_rule_refinement.csv", index=False)
        (args.out / "face_rule_refinement.md").write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
