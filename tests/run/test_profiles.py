"""An ensemble's energy profile (`pinnedballs.run.profiles`; issue 49, item 11d): each replica's share of the
energy by row from the boundary, kept apart from the table's columns, written beside it and read back bit for
bit, and its mean over the replicas drawn as a single run's energy_by_distance figure is."""

from __future__ import annotations

import numpy as np
from helpers import HALF_PLANE, TORUS
from matplotlib.image import imread

from pinnedballs.analysis import observables as obs
from pinnedballs.run import ensemble as ens
from pinnedballs.run import ensemble_files as ens_files
from pinnedballs.run import profiles
from pinnedballs.run.ensemble_dir import load_ensemble
from pinnedballs.specs import parse_spec


def test_each_row_keeps_its_profile_a_partition_of_the_energy_apart_from_the_columns():
    spec = parse_spec(HALF_PLANE)
    result = ens.run_ensemble(spec, 3, workers=1)
    rows = len(obs.boundary_rows(spec.geometry.build().boundary.distance)[1])
    for row in result.rows:
        shares = np.asarray(row[profiles.PROFILE])
        assert len(shares) == rows and abs(shares.sum() - 1) <= 1e-12
        assert np.allclose([shares[0], shares[-1]], [row["boundary_share"], row["far_row_share"]], rtol=1e-14, atol=0)
    assert profiles.PROFILE not in result.columns and profiles.PROFILE not in result.to_pandas().columns
    assert ens.run_replica(spec, 1) == [r for r in result.rows if r["replica"] == 1]  # run alone: the same rows


def test_the_profiles_are_written_beside_the_table_and_read_back_bit_for_bit(tmp_path):
    result = ens.run_ensemble(parse_spec(HALF_PLANE), 3, workers=1)
    written = ens_files.write_outputs(result, tmp_path / "e")
    assert tmp_path / "e" / profiles.PROFILES_NAME in written
    back = load_ensemble(tmp_path / "e")
    assert back.rows == result.rows
    def bits(row):
        return np.array(row[profiles.PROFILE]).view(np.uint64)

    assert all(np.array_equal(bits(a), bits(b)) for a, b in zip(back.rows, result.rows))  # bit for bit


def test_the_mean_profile_is_drawn_where_the_geometry_has_a_boundary_only(tmp_path):
    result = ens.run_ensemble(parse_spec(HALF_PLANE), 4, workers=1)
    (final,) = [p for p in ens_files.write_figures(result, tmp_path) if p.name == "energy_by_distance_final.png"]
    assert imread(final).shape[2] in (3, 4)
    mean, n = profiles.mean_profiles(result.rows, ens.ERROR_COLUMN)["final"]
    shares = np.array([r[profiles.PROFILE] for r in result.rows if r["at"] == "final"])
    assert n == 4 and np.array_equal(mean, shares.mean(axis=0))
    from pinnedballs.plot.figures import energy_bars

    centres = obs.boundary_rows(result.spec.geometry.build().boundary.distance)[1]
    ax = energy_bars(centres, mean).axes[0]
    assert [bar.get_height() for bar in ax.patches] == mean.tolist()
    torus = ens.run_ensemble(parse_spec(TORUS), 2, workers=1)
    assert not [p for p in ens_files.write_outputs(torus, tmp_path / "t") if "energy" in p.name or "profiles" in p.name]
    assert not (tmp_path / "t" / profiles.PROFILES_NAME).exists()
