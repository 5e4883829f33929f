"""rangekit.plot.girard2011: Figs 11-13-like clouds, Fig. 10-like paths, error curves."""

from __future__ import annotations

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError
from rangekit.localize.particle import Cloud, ParticleConfig, track_particles
from rangekit.plot import new_figure, save_figure
from rangekit.plot.girard2011 import (
    draw_cloud,
    draw_walls,
    figure_clouds,
    figure_errors,
    figure_paths,
)
from rangekit.sim.girard2011 import simulate


@pytest.fixture(scope="module")
def walk():
    sim = simulate(rng=0)
    trk = track_particles(
        sim.plan, sim.steps, sim.ranges, sim.start_m, ParticleConfig(), rng=0,
        save_clouds=(9, 21, 52),
    )  # fmt: skip
    return sim, trk


@pytest.mark.parametrize("suffix", [".png", ".svg"])
def test_figure_clouds_writes_file(tmp_path, walk, suffix):
    sim, trk = walk
    out = figure_clouds(
        tmp_path / f"clouds{suffix}",
        walls_m=sim.plan.segments,
        truth_m=sim.truth_m,
        estimate_m=trk.xy_m,
        clouds=trk.clouds,
        start_m=sim.start_m,
        title="with ranging (Fig. 13)",
    )
    assert out == tmp_path / f"clouds{suffix}" and out.stat().st_size > 10_000
    if suffix == ".svg":
        text = out.read_text()
        for label in ("after 9 steps", "after 21 steps", "after 52 steps", "Fig. 13",
                      "x (m)", "true position", "particles (150)"):  # fmt: skip
            assert label in text


def test_draw_cloud_draws_every_particle_and_the_extent(tmp_path, walk):
    sim, trk = walk
    fig, ax = new_figure()
    a = ax[0, 0]
    walls = draw_walls(a, sim.plan.segments)
    assert len(walls) == sim.plan.segments.shape[0]
    cloud = trk.clouds[1]
    art = draw_cloud(a, cloud, truth_m=sim.truth_m, estimate_m=trk.xy_m, start_m=sim.start_m)
    scat = next(x for x in art if hasattr(x, "get_offsets"))
    np.testing.assert_array_equal(np.sort(scat.get_offsets(), axis=0), np.sort(cloud.xy_m, axis=0))
    circle = next(x for x in art if x.get_label() == "cloud extent").get_xydata()
    r = np.hypot(*(circle - trk.xy_m[20]).T)
    far = np.max(np.hypot(*(cloud.xy_m - trk.xy_m[20]).T))
    np.testing.assert_allclose(r, far)  # through the farthest particle
    true_path = next(x for x in art if x.get_label() == "true path").get_xydata()
    assert true_path.shape == (22, 2)  # start + 21 steps
    assert "after 21 steps" in a.get_title()
    save_figure(fig, tmp_path / "one.png")  # closes the figure


def test_figure_paths_and_errors(tmp_path, walk):
    sim, trk = walk
    p = figure_paths(
        tmp_path / "paths.svg",
        walls_m=sim.plan.segments,
        paths={"true": sim.truth_m, "dead reckoning": sim.dead_reckoning_m, "est": trk.xy_m},
        start_m=sim.start_m,
        title="Fig. 10",
    )
    text = p.read_text()
    assert "dead reckoning" in text and "start" in text and "Fig. 10" in text
    e = figure_errors(
        tmp_path / "err.svg",
        errors_m={"a": np.hypot(*(trk.xy_m - sim.truth_m).T), "b": np.linspace(0, 1, 52)},
        styles={"b": "k:"},
        title="errors",
    )
    text = e.read_text()
    assert "distance from the true position (m)" in text and "step" in text


def test_bad_inputs(tmp_path, walk):
    sim, trk = walk
    kw = {"walls_m": sim.plan.segments, "truth_m": sim.truth_m, "estimate_m": trk.xy_m}
    with pytest.raises(InvalidParameterError, match="clouds"):
        figure_clouds(tmp_path / "a.png", clouds=[], **kw)
    late = Cloud(60, np.zeros((1, 2)), np.ones(1))
    with pytest.raises(InvalidParameterError, match="after_steps=60"):
        figure_clouds(tmp_path / "a.png", clouds=[late], **kw)
    with pytest.raises(InvalidParameterError, match="format"):
        figure_clouds(tmp_path / "a.txt", clouds=trk.clouds[:1], **kw)
    with pytest.raises(InvalidParameterError, match="errors_m"):
        figure_errors(tmp_path / "e.png", errors_m={})
    with pytest.raises(InvalidParameterError, match=r"paths\['x'\]"):
        figure_paths(tmp_path / "p.png", walls_m=sim.plan.segments, paths={"x": [1.0, 2.0]})
    assert not list(tmp_path.iterdir())
