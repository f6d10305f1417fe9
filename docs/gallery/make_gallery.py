"""Make the gallery: run each example spec of ``GALLERY``, copy its figures into ``docs/gallery/``
and write ``docs/gallery.md`` with each spec's JSON beside the figures it made.

    python3 docs/gallery/make_gallery.py

Runs ``pinnedballs run`` on each spec (a few seconds each) in a temporary directory, so the
page shows exactly what a user gets from the same command (the first and last states, a contact
sheet of the snapshots, the energy and the velocity histograms); the half-plane also gets its
movie (``pinnedballs animate``).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HERE = ROOT / "docs" / "gallery"
PAGE = ROOT / "docs" / "gallery.md"

#: (name, title, the example spec, what to say about it, make a movie)
GALLERY = (
    ("half_plane", "The half-plane", "gallery_half_plane.json",
     "The paper's system, small: energy enters at the boundary's centre, spreads, and freezes. In so "
     "small a rectangle the far side keeps more of it than the boundary row (30 % against 21 %).", True),
    ("torus", "The flat torus", "gallery_torus.json",
     "Periodic: it never freezes, and the components approach a normal law (the histograms' "
     "Anderson-Darling verdict says how close).", False),
    ("sphere", "The sphere", "gallery_sphere.json",
     "Both hemispheres seen from outside; arrows are the tangent velocities in the picture plane.", False),
    ("hyperbolic", "The hyperbolic disk", "gallery_hyperbolic.json",
     "The {3,7} tiling in the Poincare disk: balls and arrows at their hyperbolic sizes carried to the "
     "disk, so they shrink towards the rim. The outermost ring is the boundary.", False),
    ("fcc", "An FCC half-space", "gallery_fcc.json",
     "A 3-D packing with its boundary at z = 0, kicked straight up: the state pictures show every layer "
     "seen from above, v_z as colour (red up, blue down) and (v_x, v_y) as arrows; the energy is given by "
     "distance from the boundary and by height.", False),
)


def run(*argv: str) -> str:
    done = subprocess.run([sys.executable, "-m", "pinnedballs", *argv], cwd=ROOT, check=True,
                          capture_output=True, text=True)
    return done.stdout


def make(name: str, spec_name: str, movie: bool, work: Path) -> list[str]:
    """Run the spec, copy its figures in as ``<name>_<figure>.png``; their file names, in order."""
    out = work / name
    run("run", str(ROOT / "examples" / spec_name), "--out", str(out), "--quiet")
    drawn = run("plot", str(out)).split()  # what plot says it wrote, in the order it drew them
    names = []
    for figure in map(Path, drawn):
        target = f"{name}_{figure.name}"
        shutil.copyfile(figure, HERE / target)
        names.append(target)
    if movie:
        run("animate", str(out), "--out", str(HERE / f"{name}_movie.gif"), "--fps", "3")
        names.append(f"{name}_movie.gif")
    return names


def page(sections: list[tuple[str, str, str, str, list[str]]]) -> str:
    lines = ["# Gallery", "",
             "Each figure beside the spec that made it: `pinnedballs run SPEC --out DIR` draws them "
             "(`pinnedballs plot DIR` again, `pinnedballs animate DIR` the movie). The specs are in "
             "`examples/`; `python3 docs/gallery/make_gallery.py` makes this page again.", ""]
    for title, spec_name, text, spec_text, figures in sections:
        lines += [f"## {title}", "", text, "", f"`examples/{spec_name}`:", "", "```json", spec_text.rstrip(), "```", ""]
        for figure in figures:
            lines += [f"![{title}: {figure}](gallery/{figure})", ""]
    return "\n".join(lines)


def main() -> None:
    for old in HERE.glob("*.png"):
        old.unlink()
    for old in HERE.glob("*.gif"):
        old.unlink()
    sections = []
    with tempfile.TemporaryDirectory() as work:
        for name, title, spec_name, text, movie in GALLERY:
            figures = make(name, spec_name, movie, Path(work))
            spec_text = (ROOT / "examples" / spec_name).read_text(encoding="utf-8")
            sections.append((title, spec_name, text, spec_text, figures))
            print(f"{title}: {len(figures)} figures", flush=True)
    PAGE.write_text(page(sections), encoding="utf-8")
    print(f"wrote {PAGE}")


if __name__ == "__main__":
    main()
