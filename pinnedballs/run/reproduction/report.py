"""``report.md``: the set-up, the table of checks, notes and the figures."""

from __future__ import annotations

import math
import os

from .. import ensemble as ens
from .checks import Check
from .plan import CORRELATION_TOLERANCE, Plan, _label, _sizes, expected_figures


def _yes(flag: bool | None) -> str:
    return {True: "**yes**", False: "**no**", None: "—"}[flag]


# ---------------------------------------------------------------- the report


def _report(plan: Plan, quick: bool, checks: list[Check], results: dict, geom, torus, lattice,
            failures: list[dict], wall: float) -> str:
    agree = sum(c.agrees is True for c in checks)
    compared = sum(c.agrees is not None for c in checks)
    sizes = ", ".join(_label(s) for s in _sizes(plan))
    lines = [
        f"# Reproduction of *Pinned Billiard Balls Simulation* (WXML 2023){' — quick run' if quick else ''}",
        "",
        f"Wall time: **{wall:.1f} s** on {os.cpu_count()} core(s) for `pinnedballs reproduce"
        f"{' --quick' if quick else ''}` (Python start-up and imports, a few seconds, not included); "
        f"{agree} of {compared} comparisons agree.",
        "",
        "## Set-up",
        "",
        f"* Half-plane: `HalfPlane.from_size(L, D)` for {sizes}; the boundary ball nearest the middle "
        f"(`boundary_center()`) starts with velocity along (0, 1), into the bulk, energy {plan.energy:g}, masses 1; "
        f"run until frozen. Figures 1-3 use {_label(plan.detail)} = {geom.rows} rows of {geom.cols} = "
        f"{geom.n_balls:,} balls.",
        f"* Paper orientation (cross-check): the paper's 100x50 holds 1,425 = 57 x 25 balls, which fits lattice rows "
        f"*perpendicular* to the boundary (a zig-zag boundary of balls at distances 0 and 1); our `HalfPlane` has rows "
        f"parallel to it. We also ran that lattice ({lattice.n_balls:,} balls, "
        f"`HalfPlane.from_size(L, D, orientation=\"across\")`), same initial condition.",
        f"* Flat torus: the paper gives no size; we use `FlatTorus({torus.rows}, {torus.cols})` = {torus.n_balls:,} "
        f"balls, about the {_label(plan.detail)} half-plane's count. Ball 0 moves along (1, 0) with energy "
        f"{plan.energy:g}; snapshots at {', '.join(f'{s:,}' for s in plan.steps)} steps (a step is one pick of a "
        "contact; the paper's captions say collisions, but a 100x50 half-plane freezes after ~48,000 collisions, "
        "so these counts must be steps).",
        f"* Seeds: single runs (the pictures) use seed {plan.seed}; ensembles use replicas 0..N-1 of seed "
        f"{plan.seed} (`SeedSequence({plan.seed}).spawn(N)`): {plan.replicas} runs of the torus, of the "
        f"{_label(plan.detail)} half-plane and of the paper-orientation lattice, {plan.size_replicas} of each other "
        "rectangle. Every replica's row is in `ensembles/<name>/replicas.csv`; the specs are in `specs/`.",
        "",
        "## Statements of the paper against our measurements",
        "",
        "| # | Statement | Paper | Ours | Criterion | Agrees |",
        "|---|---|---|---|---|---|",
    ]
    cell = lambda text: text.replace("|", "\\|")  # noqa: E731 - a pipe would end the cell
    for k, c in enumerate(checks, 1):
        lines.append(f"| {k} | {cell(c.statement)} | {cell(c.paper)} | {cell(c.ours)} | {cell(c.criterion)} | "
                     f"{_yes(c.agrees)} |")
    torus_n, E = torus.n_balls, plan.energy
    lines += [
        "",
        "## Notes",
        "",
        f"* **Equilibrium in the torus.** Energy E = {E:g} and momentum P = (sqrt(2E), 0) are conserved (unit "
        f"masses). At equilibrium the internal energy E - |P|^2/(2N) is shared by 2(N - 1) degrees of freedom, so each "
        f"component has mean P/N ({math.sqrt(2 * E) / torus_n:.4f} for x, 0 for y: the paper's mean 0 is exact "
        f"only for y) and variance (2E - |P|^2/N) / (2(N - 1)) = E/N = {E / torus_n:.4f} exactly for this start. "
        "The sum of the two sample variances is fixed by the conservation laws, so what equilibrium adds is "
        "their equal split and the normal shape — which is what the rows above test.",
        "* **Frozen against running.** In a frozen state every contact has u ≤ u' (no contact approaches), so its "
        "line-of-centres correlation is strongly positive (the row above); the near-zero correlation of the paper "
        "is a statement about the running torus.",
        "* **The collision chain is not uniform on the energy sphere.** A contact collides only when it approaches, "
        "and a collision turns it receding, so receding contacts are over-represented: fewer than half of the "
        "torus's contacts approach at any time (last torus row), where the uniform law on the sphere would give "
        "one half.",
        "* **Orientation of the half-plane lattice.** Our `HalfPlane` boundary row holds a whole lattice row; the "
        "paper's count (1,425 balls) fits the other orientation, whose distance-0 share (about 30 %) and collisions "
        "until frozen are the paper's figures. See the rows marked 'paper's orientation'.",
        "* Criteria are stated before comparing and are deliberately simple: 'about 30 %' as 30 ± 10 points, "
        f"'near 0' as |mean| ≤ {CORRELATION_TOLERANCE}; a '**no**' marks a real difference, explained in "
        "`docs/reproduce.md`.",
    ]
    if failures:
        lines += ["", "## Failed replicas", ""]
        lines += [f"* {f['ensemble']}: replica {f['replica']} (seed entropy {f['seed_entropy']}, spawn key "
                  f"{f['spawn_key']}): {f[ens.ERROR_COLUMN]}" for f in failures]
    lines += ["", "## Figures", ""]
    lines += [f"* ![{name}]({name})" for name in expected_figures(plan)]
    return "\n".join(lines) + "\n"
