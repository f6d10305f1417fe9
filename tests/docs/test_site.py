"""The documentation a new user meets: every extra it advises exists, the first command can run twice,
the home page lists every page, one time for ``reproduce --quick`` everywhere, and a site that works
offline (no web fonts) with a 404 page whose links work under any path."""

from __future__ import annotations

import importlib.util
import re
import tomllib
from pathlib import Path

import pytest
from helpers import HALF_PLANE, call, spec, write

from pinnedballs.plot.animation import MP4_MISSING
from pinnedballs.run.cli.commands import COMMANDS

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def text(path: Path) -> str:
    return path.read_text(encoding="utf-8")


def mkdocs() -> str:
    return text(ROOT / "mkdocs.yml")


# ---------------------------------------------------------------- 5.2: the extras the docs advise


def test_every_extra_the_docs_advise_is_in_pyproject_and_installs_from_the_checkout():
    extras = tomllib.loads(text(ROOT / "pyproject.toml"))["project"]["optional-dependencies"]
    advised = []
    for source in [*PAGES, *ROOT.glob("pinnedballs/**/*.py")]:
        for package, extra in re.findall(r"pip install \\?[\"']?([\w.-]*)\[(\w+)\]", text(source)):
            advised.append((source.name, package, extra))
    assert {extra for _, _, extra in advised} == {"test", "docs", "movies", "cuda", "notebook", "dask", "gsd", "pandas",
                                                  "xarray"}
    for name, package, extra in advised:
        assert extra in extras, (name, extra)
        assert package == ".", f"{name}: pip install {package}[{extra}] (pinnedballs is installed from its checkout)"
    assert any(r.startswith("imageio-ffmpeg") for r in extras["movies"])   # what writing MP4 imports
    assert 'pip install ".[movies]"' in MP4_MISSING


def extras() -> dict[str, list[str]]:
    return tomllib.loads(text(ROOT / "pyproject.toml"))["project"]["optional-dependencies"]


def names(requirements: list[str]) -> set[str]:
    return {re.match(r"[\w.-]+", r).group(0).lower() for r in requirements}


def test_the_notebook_extra_opens_the_tutorials_and_runs_them_headless():
    """The README's tutorials need jupytext, and its headless command nbclient and a kernel: the notebook extra
    installs them, and the README gives the command."""
    assert {"jupyterlab", "ipywidgets", "jupytext", "nbclient", "ipykernel"} <= names(extras()["notebook"])
    readme = text(ROOT / "README.md")
    assert 'pip install ".[notebook]"' in readme
    assert re.search(r"^jupytext --to notebook --execute docs/tutorials/\w+\.py", readme, flags=re.M)


def readme_commands() -> list[str]:
    """The README's command lines that install and then run something (``python3 -m pip install ... && ...``)."""
    return re.findall(r"^python3 -m pip install \S+ && .+$", text(ROOT / "README.md"), flags=re.M)


def test_ci_runs_each_readme_command_as_written_in_a_fresh_environment():
    """The quick start's two lines and the documentation's, read out of the README by .ci/run (so they cannot
    drift apart), each after a fresh virtual environment of its own: an install step an extra lacks fails CI."""
    ci = text(ROOT / ".ci" / "run")
    commands = readme_commands()
    assert [c.split(" && ")[0] for c in commands] == [
        "python3 -m pip install .", 'python3 -m pip install ".[test]"', 'python3 -m pip install ".[docs]"']
    assert commands[1].endswith("python3 -m pytest -q") and commands[2].endswith("mkdocs build --strict")
    at = []
    for command in commands:
        head = command.split(" && ")[0] + " && "
        read = ci.index(f"line=$(readme_line '{head}')")
        assert ci.rindex("\nfresh ", 0, read) > (at[-1] if at else -1), head    # its own fresh environment
        later = ci.find("\nfresh ", read)
        assert -1 < ci.index('bash -c "$line"', read) < (later if later > -1 else len(ci)), head   # run there
        at.append(read)


def test_the_test_extra_leaves_numba_cuda_to_the_cuda_extra_and_ci_runs_the_gpu_tests_with_it():
    """numba-cuda pulls about 520 MB of CUDA packages: `.[test]` leaves it out and the GPU tests skip without it
    (the ``cuda`` marker, tests/conftest.py); CI then adds `.[cuda]` and runs them (``-m cuda``), checking that
    it imports, so that none is skipped there."""
    assert "numba-cuda" not in names(extras()["test"]) and "numba-cuda" in names(extras()["cuda"])
    ci = text(ROOT / ".ci" / "run")
    suite = ci.index("line=$(readme_line 'python3 -m pip install \".[test]\" && ')")
    cuda = ci.index('pip install --quiet --disable-pip-version-check ".[cuda]"')
    assert suite < cuda < ci.index('python3 -c "import numba_cuda"') < ci.index("python3 -m pytest -q -m cuda")


#: what a test module does that needs numba-cuda: the GPU engine, a run on device "cuda", its command line
GPU_USE = re.compile(r"device=[\"']cuda[\"']|\"--device\", \"cuda\"|engine\.gpu|numba_cuda|from numba import cuda")


def test_every_test_of_the_gpu_is_marked_cuda():
    """A test module that uses the GPU engine marks its tests ``cuda`` (all, or those that use it), which skip,
    saying so, without numba-cuda; `test_public_warnings` runs a GPU call without numba-cuda on purpose, and
    `test_provenance` only names the package in what a run records."""
    using = [path for path in sorted((ROOT / "tests").rglob("test_*.py")) if GPU_USE.search(text(path))
             and path.name not in ("test_public_warnings.py", "test_site.py", "test_provenance.py")]
    assert len(using) >= 10
    assert [path.relative_to(ROOT).as_posix() for path in using if "pytest.mark.cuda" not in text(path)] == []


# ---------------------------------------------------------------- 5.3: the first command, the home page


def first_command(page: Path) -> list[str]:
    line = re.search(r"^python3 -m pinnedballs run .*$", text(page), flags=re.M).group(0)
    return line.split()[3:]                                             # after "python3 -m pinnedballs"


@pytest.mark.parametrize("page", ["getting-started.md", "index.md"])
def test_the_first_command_runs_twice(tmp_path, page):
    """The page's first command, on a small spec and directory of its own, with all its flags."""
    argv = first_command(ROOT / "docs" / page)
    assert argv[0] == "run" and "--force" in argv
    small = write(tmp_path / "small.json", spec(HALF_PLANE))
    argv = [str(small) if a.endswith(".json") else str(tmp_path / "out") if a.startswith("results/") else a
            for a in argv]
    for _ in range(2):
        code, _, err = call(*argv, "--quiet", "--no-figures")
        assert code == 0, err


def test_the_home_page_lists_every_page_of_the_site():
    nav = re.findall(r"^\s+- [^:]+: (\S+\.md)$", mkdocs(), flags=re.M)
    assert len(nav) >= 11 and "gallery.md" in nav and "orders.md" in nav and "trajectories.md" in nav
    listed = set(re.findall(r"\]\((\S+\.md)\)", text(ROOT / "docs" / "index.md")))
    assert listed == set(nav) - {"index.md"}


# ---------------------------------------------------------------- 5.8: one time for reproduce --quick


def test_reproduce_quick_takes_the_same_time_in_the_help_the_readme_and_the_docs():
    said = "about 10 seconds on a quiet 2-core machine"  # timings hold on a quiet machine only: each says so
    (quick,) = [o for flags, o in COMMANDS["reproduce"].arguments if "--quick" in flags]
    assert said in quick["help"]
    for page in (ROOT / "README.md", ROOT / "docs" / "reproduce.md"):
        lines = [line for line in text(page).splitlines() if "--quick" in line and "--extended" not in line
                 and re.search(r"\d+ ?s\b|second|minute", line)]  # --extended --quick is another run
        assert lines and all(said in line for line in lines), (page.name, lines)


# ---------------------------------------------------------------- 5.10: a site that works offline


def test_the_site_uses_no_web_fonts_and_wraps_long_code_lines():
    assert re.search(r"^  font: false", mkdocs(), flags=re.M)
    css = [ROOT / "docs" / c for c in re.findall(r"^  - (stylesheets/\S+\.css)", mkdocs(), flags=re.M)]
    assert css and any(re.search(r"pre > code \{[^}]*white-space: pre-wrap", text(c)) for c in css)


def test_the_404_page_links_relative_to_the_site_root_like_every_other_page():
    """mkdocs writes 404.html with root-absolute links; the hook in mkdocs.yml rewrites them (the built
    page itself is checked by .ci/run after building the site, where mkdocs is installed)."""
    assert "docs/_hooks/relative_404.py" in mkdocs() and "/_hooks/" in mkdocs()
    spec_ = importlib.util.spec_from_file_location("relative_404", ROOT / "docs" / "_hooks" / "relative_404.py")
    hook = importlib.util.module_from_spec(spec_)
    spec_.loader.exec_module(hook)
    page = ('<link href="/assets/stylesheets/main.css"><a href="/.">home</a><a href="/gallery/">'
            '<script src="/assets/javascripts/bundle.js"></script><a href="https://x.org/">'
            '<a href="//cdn.example/x"><script id="__config">{"base": "/", "features": []}</script>')
    assert hook.relative(page) == (
        '<link href="./assets/stylesheets/main.css"><a href="./.">home</a><a href="./gallery/">'
        '<script src="./assets/javascripts/bundle.js"></script><a href="https://x.org/">'
        '<a href="//cdn.example/x"><script id="__config">{"base": ".", "features": []}</script>')
