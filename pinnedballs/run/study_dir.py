"""A study directory read back (`run.study` writes it): `load_study` gives a `StudyResult`, which reads the
points' ensembles only when asked (`StudyResult.to_pandas`, `StudyResult.summary`, ...), and `describe` the lines
``pinnedballs info`` prints of it.

The table has a row per replica of each point done (its final state; every state with ``at=None``): the point's
place in the study (``point``) and signac job (``job``), the values of the paths the study varies (a column each,
named by its path: ``geometry.length``), the number of balls (``n_balls``), then the point's ensemble's columns
(`run.ensemble.EnsembleResult.to_pandas`). `StudyResult.summary` has a row per point: ``replicas`` (those that
gave a row), then ``<observable>_mean``, ``_sd`` (``ddof=1``) and ``_se`` (sd over the square root of the count)
of each observable, the names the extended reproduction's tables use.
"""

from __future__ import annotations

import json
import math
import os
from functools import cached_property
from pathlib import Path

import numpy as np

from ..util.errors import InputError
from ..util.extras import need
from . import ensemble as ens
from .ensemble_dir import is_ensemble_dir, load_ensemble

__all__ = ["StudyResult", "load_study", "is_study_dir", "describe", "LENGTHS", "STUDY_NAME", "POINTS_NAME",
           "ENSEMBLE_DIR", "PARTIAL_DIR"]

#: the files of a study directory (`run.study`): the study as run, its points, and in each job the point's ensemble
#: (written as `PARTIAL_DIR`, renamed when whole)
STUDY_NAME, POINTS_NAME, ENSEMBLE_DIR, PARTIAL_DIR = "study.json", "points.json", "ensemble", "ensemble.partial"

#: paths measured in ball radii (an axis label's unit)
LENGTHS = ("geometry.length", "geometry.depth", "geometry.radius")
#: the points `describe` lists, at most
SHOWN = 40
#: columns of an ensemble's table that are not observables (left out of `StudyResult.summary`)
_KEYS = ("replica", "seed_entropy", "spawn_key", "at", "stop_reason", ens.ERROR_COLUMN)


def is_study_dir(path: str | os.PathLike) -> bool:
    """True when ``path`` is a directory `run_study` wrote: a signac project with ``study.json`` and ``points.json``."""
    p = Path(path)
    return p.is_dir() and (p / POINTS_NAME).is_file() and (p / STUDY_NAME).is_file() and (p / ".signac").is_dir()


def _json(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{path}: missing (not a study directory, or an incomplete one)") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{path}: not readable JSON ({' '.join(str(exc).split())})") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: must hold a JSON object")
    return data


def load_study(path: str | os.PathLike) -> StudyResult:
    """The `StudyResult` in a study directory (`run_study`'s, ``pinnedballs study``'s).

    Parameters
    ----------
    path : str or os.PathLike
        The directory.

    Returns
    -------
    StudyResult
        Its points; their ensembles are read when used.

    Raises
    ------
    InputError
        Naming the file if it is not one: no such directory, no ``points.json``, ``study.json`` and
        ``.signac/``, or a file that does not parse.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> base = {"geometry": {"kind": "half_plane", "rows": 4, "cols": 6},
    ...         "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1], "energy": 0.5},
    ...         "stop": {"frozen": True, "max_steps": 100000}}
    >>> study = {"base": base, "grid": {"geometry.cols": [6, 8]}, "replicas": 2, "seed": 0}
    >>> pb.run_study(study, "study", workers=1)
    StudyResult(study: 2 of 2 points done, varying geometry.cols)
    >>> st = pb.load_study("study")
    >>> st.summary(["collisions"])[["geometry.cols", "n_balls", "collisions_mean", "collisions_se"]]
       geometry.cols  n_balls  collisions_mean  collisions_se
    0              6       24             46.5            6.5
    1              8       32             84.5            4.5
    >>> round(st.fit("collisions", against="n_balls")["exponent"], 3)
    2.076
    """
    out = Path(path)
    if not out.is_dir():
        raise InputError(f"{out}: no such directory")
    if not is_study_dir(out):
        raise InputError(f"{out}: not a study directory (no {POINTS_NAME}, {STUDY_NAME} and .signac/)")
    record, study = _json(out / POINTS_NAME), _json(out / STUDY_NAME)
    points = record.get("points")
    if not isinstance(points, list) or not all(isinstance(p, dict) and {"job", "overrides", "replicas", "n_balls"}
                                                <= set(p) for p in points):
        raise InputError(f"{out / POINTS_NAME}: points: must be a list of points (job, overrides, replicas, n_balls)")
    return StudyResult(out, study, points)


class StudyResult:
    """A study directory and its points' ensembles, read when used (`load_study`, `run_study`).

    Parameters
    ----------
    path : pathlib.Path
        The directory.
    study : dict
        The study as run, JSON.
    points : list of dict
        Each one's ``job``, ``overrides``, ``replicas``, ``seed`` and ``n_balls``, in the study's order.

    Attributes
    ----------
    ran : list of int
        The points `run_study` ran in the call that returned this (by place).
    """

    def __init__(self, path: Path, study: dict, points: list[dict]):
        self.path, self.study, self.points = Path(path), study, points
        self.ran: list[int] = []  #: the points `run_study` ran in the call that returned this (by place)
        self._ensembles: dict[int, ens.EnsembleResult] = {}

    # ------------------------------------------------------------ the points
    @cached_property
    def varied(self) -> list[str]:
        """The paths the study varies, in the order its points give them."""
        return list(dict.fromkeys(p for point in self.points for p in point["overrides"]))

    def job_dir(self, k: int) -> Path:
        """The signac job directory of a point.

        Parameters
        ----------
        k : int
            The point's place in the study.

        Returns
        -------
        pathlib.Path
            ``path/workspace/<job id>``.
        """
        return self.path / "workspace" / str(self.points[k]["job"])

    def done(self) -> list[bool]:
        """For each point, whether its ensemble is whole in its job (looked at now).

        Returns
        -------
        list of bool
        """
        return [is_ensemble_dir(self.job_dir(k) / ENSEMBLE_DIR) for k in range(len(self.points))]

    def ensemble(self, k: int) -> ens.EnsembleResult:
        """The ensemble of a point (read once).

        Parameters
        ----------
        k : int
            The point's place in the study.

        Returns
        -------
        EnsembleResult

        Raises
        ------
        InputError
            If it has not run yet, naming the point.
        """
        if k not in self._ensembles:
            where = self.job_dir(k) / ENSEMBLE_DIR
            if not is_ensemble_dir(where):
                raise InputError(f"point {k} {json.dumps(self.points[k]['overrides'])}: not run yet (no {where}); "
                                 f"run the study again with resume=True (--resume)")
            self._ensembles[k] = load_ensemble(where)
        return self._ensembles[k]

    def _values(self, k: int) -> dict:
        """Point ``k``'s value of each varied path: its override, else its run spec's."""
        overrides = self.points[k]["overrides"]
        spec = None
        values = {}
        for path in self.varied:
            if path in overrides:
                values[path] = overrides[path]
                continue
            spec = self.ensemble(k).spec.model_dump(mode="json") if spec is None else spec
            node = spec
            for key in path.split("."):
                node = node.get(key) if isinstance(node, dict) else None
            values[path] = node
        return values

    # ------------------------------------------------------------ tables
    def to_pandas(self, at: str | None = ens.FINAL):
        """The table of the points done, a row per replica of each (its columns: the module's docstring).

        Parameters
        ----------
        at : str or None
            A stage (the final state by default): a row per replica; None: every row (snapshots too).

        Returns
        -------
        pandas.DataFrame
        """
        pd = need("pandas", "to_pandas", "pandas")

        frames = []
        for k, done in enumerate(self.done()):
            if not done:
                continue
            df = self.ensemble(k).to_pandas(at=at).reset_index()
            head = {"point": k, "job": self.points[k]["job"], **self._values(k), "n_balls": self.points[k]["n_balls"]}
            for n, (name, value) in enumerate(head.items()):
                df.insert(n, name, [value] * len(df))
            frames.append(df)
        if not frames:
            return pd.DataFrame(columns=["point", "job", *self.varied, "n_balls", "replica"])
        return pd.concat(frames, ignore_index=True)

    def summary(self, observables: list[str] | None = None, at: str = ens.FINAL):
        """The observables' means and errors, a row per point done.

        Parameters
        ----------
        observables : list of str, optional
            Default: every numeric column of the ensembles' tables.
        at : str
            The stage (the final state by default).

        Returns
        -------
        pandas.DataFrame
            ``point``, ``job``, the varied paths, ``n_balls``, ``replicas`` (those with a row at ``at``), then
            ``<name>_mean``, ``<name>_sd`` and ``<name>_se`` of each observable.
        """
        pd = need("pandas", "a study's summary, fit and figure", "pandas")

        rows = []
        for k, done in enumerate(self.done()):
            if not done:
                continue
            res = self.ensemble(k)
            names = observables if observables is not None else _numeric(res)
            row = {"point": k, "job": self.points[k]["job"], **self._values(k), "n_balls": self.points[k]["n_balls"],
                   "replicas": sum(1 for r in res.rows if not r.get(ens.ERROR_COLUMN) and r.get("at") == at)}
            for name in names:
                row.update(_stats(name, res.column(name, at)))
            rows.append(row)
        return pd.DataFrame(rows)

    def fit(self, observable: str = "collisions", against: str = "n_balls", where: dict | None = None) -> dict:
        """The power law ``mean ~ C x^a`` of an observable over the points done, weighted by the standard errors.

        Parameters
        ----------
        observable : str
            A column of the study's tables.
        against : str
            ``"n_balls"`` or a varied path.
        where : dict, optional
            ``{path: value}``: only the points it holds for.

        Returns
        -------
        dict
            `run.reproduction.fit.fit_exponent`'s (``exponent``, ``exponent_se``, ``prefactor``, ...), the local
            exponents between consecutive values (`run.reproduction.fit.local_exponents`), and ``x``, ``mean``
            and ``se``: the points fitted, by ``x``.

        Raises
        ------
        InputError
            On ``against`` (neither ``n_balls`` nor a varied path, values that are not numbers, or one value at
            several points), ``observable`` or ``where``, or where the fit fails.
        """
        from .reproduction.fit import fit_exponent, local_exponents

        x, mean, se = self._series(observable, against, where)
        if len(set(x.tolist())) != len(x):
            raise InputError(f"against: {against} takes one value at several points; fit a part of the study "
                             f"(where={{path: value}})")
        try:
            fitted = fit_exponent(x, mean, se)
        except ValueError as exc:
            raise InputError(f"{observable} against {against}: {exc}") from None
        return {**fitted, **local_exponents(x, mean, se), "x": x.tolist(), "mean": mean.tolist(), "se": se.tolist()}

    def _series(self, observable: str, against: str, where: dict | None) -> tuple[np.ndarray, ...]:
        """``(x, mean, se)`` of the points done that ``where`` holds for, by ``x``."""
        table = self.summary([observable])
        if against != "n_balls" and against not in self.varied:
            raise InputError(f"against: {against!r} is neither n_balls nor a path the study varies "
                             f"({', '.join(self.varied) or 'none'})")
        if f"{observable}_mean" not in table:
            raise InputError(f"observable: {observable!r} is not a column of the study's tables")
        for path, value in (where or {}).items():
            if path not in table:
                raise InputError(f"where: {path!r} is not a path the study varies ({', '.join(self.varied)})")
            table = table[table[path].map(lambda v, value=value: v == value)]
        try:
            x = table[against].to_numpy(dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"against: {against} takes values that are not numbers "
                             f"({', '.join(map(json.dumps, table[against].drop_duplicates()[:3]))}); draw or fit "
                             f"against n_balls or a number, the series by={[against]!r}") from None
        order = np.argsort(x, kind="stable")
        return (x[order], table[f"{observable}_mean"].to_numpy(dtype=np.float64)[order],
                table[f"{observable}_se"].fillna(0.0).to_numpy(dtype=np.float64)[order])

    # ------------------------------------------------------------ figures
    def plot(self, observable: str = "collisions", against: str = "n_balls", *, by: list[str] | None = None,
             fit: bool | None = None, log: bool | None = None, ax=None, path=None):
        """A figure of an observable (mean ± standard error over each point's replicas, final state) against
        ``against``.

        Parameters
        ----------
        observable : str
            A column of the study's tables.
        against : str
            ``"n_balls"`` or a varied path.
        by : list of str, optional
            A series for each value of these paths (default: those varied that do not move with ``against``:
            its zip partners; for ``n_balls`` the zip's paths when it varies the geometry, else the geometry's).
        fit : bool or None
            Each series' power law (`fit`) drawn with its exponent (None: against ``n_balls``, where it can be
            fitted).
        log : bool or None
            Log-log axes (None: where fitted).
        ax : matplotlib.axes.Axes, optional
            Draw into these axes; else a new figure.
        path : str or os.PathLike, optional
            Also save it there as a PNG.

        Returns
        -------
        matplotlib.figure.Figure

        Raises
        ------
        InputError
            Where no point has run yet, or on ``by``, ``against`` or a fit asked for that fails.
        """
        from ..plot.study import study_figure

        series = []
        for name, where in self._groups(against, by):
            x, mean, se = self._series(observable, against, where)
            if not len(x):
                continue
            fitted = None
            if fit or (fit is None and against == "n_balls"):
                try:
                    fitted = self.fit(observable, against, where)
                except InputError:
                    if fit:
                        raise
            series.append({"label": name, "x": x, "mean": mean, "se": se, "fit": fitted})
        if not series:
            raise InputError(f"{self.path}: no point has run yet: nothing to draw")
        fitted = any(s["fit"] is not None for s in series)
        return study_figure(series, xlabel=_axis(against), ylabel=_quantity(observable),
                            title=self.study.get("description") or f"{observable} against {against}, "
                                                                   f"{len(self.points)} points",
                            log=fitted if log is None else log, symbol="N" if against == "n_balls" else "x", ax=ax,
                            path=path)

    def _groups(self, against: str, by: list[str] | None) -> list[tuple[str, dict]]:
        """``(label, where)`` of each series: the points sharing their values of the paths ``by`` (`plot`)."""
        zipped = list(self.study.get("zip", {}))
        geometry = {p for p in self.varied if p == "geometry" or p.startswith("geometry.")}
        if against == "n_balls":
            moving = set(zipped) if geometry & set(zipped) else geometry
        else:
            moving = {against} | (set(zipped) if against in zipped else set())
        others = [p for p in self.varied if p not in moving] if by is None else list(by)
        unknown = [p for p in others if p not in self.varied]
        if unknown:
            raise InputError(f"by: {unknown[0]!r} is not a path the study varies ({', '.join(self.varied)})")
        groups: dict[str, dict] = {}
        for k, done in enumerate(self.done()):
            if done:
                values = self._values(k)
                where = {p: values[p] for p in others}
                groups.setdefault(", ".join(f"{p} = {json.dumps(v)}" for p, v in where.items()), where)
        return list(groups.items())

    # ------------------------------------------------------------ showing itself
    def _repr_html_(self) -> str:
        from ..plot.display import study_html

        return study_html(self)

    def __repr__(self) -> str:
        done = sum(self.done())
        return (f"StudyResult({self.path}: {done} of {len(self.points)} points done, varying "
                f"{', '.join(self.varied) or 'nothing'})")


def _numeric(res: ens.EnsembleResult) -> list[str]:
    """The observable columns of ``res`` (its numeric columns but the keys)."""
    return [c for c in res.columns if c not in _KEYS and len(res.column(c))]


def _stats(name: str, x: np.ndarray) -> dict[str, float]:
    """``name_mean``, ``name_sd`` (``ddof=1``) and ``name_se`` of the finite values of ``x`` (NaN where undefined)."""
    x = x[np.isfinite(x)]
    mean = float(x.mean()) if len(x) else math.nan
    sd = float(x.std(ddof=1)) if len(x) > 1 else math.nan
    return {f"{name}_mean": mean, f"{name}_sd": sd, f"{name}_se": sd / math.sqrt(len(x)) if len(x) > 1 else math.nan}


def _axis(against: str) -> str:
    if against == "n_balls":
        return "balls N"
    return f"{against} (ball radii)" if against in LENGTHS else against


def _quantity(observable: str) -> str:
    counts = {"collisions": "collisions (count)", "steps": "steps: contacts tried (count)"}
    return f"{counts.get(observable, observable.replace('_', ' '))}, mean ± se over replicas"


def describe(result: StudyResult, path: Path) -> list[str]:
    """The lines ``pinnedballs info`` prints of a study directory: its points, which are done, and each done
    one's mean collisions and steps."""
    done = result.done()
    seeds = result.study.get("seeds", "by_point")
    lines = [f"study:       {path}",
             f"points:      {sum(done)} of {len(done)} done, varying {', '.join(result.varied) or 'nothing'}",
             "seeds:       " + (f"by point, from the study's seed {result.study.get('seed')}" if seeds == "by_point"
                                else "each point's run spec's own")]
    for k, point in enumerate(result.points[:SHOWN]):
        what = f"{json.dumps(point['overrides'])}: {point['n_balls']:,} balls, {point['replicas']} replicas"
        if done[k]:
            res = result.ensemble(k)
            counts = ", ".join(f"{name} {_mean_se(res.column(name))}" for name in ("collisions", "steps"))
            failed = f", {len(res.failures)} failed" if res.failures else ""
            lines.append(f"  done  {what}{failed}; {counts}")
        else:
            lines.append(f"  to do {what}")
    if len(result.points) > SHOWN:
        lines.append(f"  ... and {len(result.points) - SHOWN:,} more points ({sum(done[SHOWN:]):,} done)")
    return lines


def _mean_se(x: np.ndarray) -> str:
    s = _stats("x", x)
    return f"{s['x_mean']:,.6g}" + (f" ± {s['x_se']:,.3g}" if math.isfinite(s["x_se"]) else "")
