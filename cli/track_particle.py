"""``rangekit track particle``: a walker on a floor plan (Girard 2011)."""

from __future__ import annotations

import dataclasses
import math

import click
from rangekit_cli._options import doc_page, shown_default
from rangekit_cli.track_common import log_argument, output_options, rig_option, write_report

from rangekit.localize.particle import (
    MAX_CANDIDATES,
    MAX_PARTICLES,
    METHODS,
    MODES,
    ParticleConfig,
)

_DEFAULTS = {f.name: f.default for f in dataclasses.fields(ParticleConfig)}
_MOUNTS_DEG = ",".join(f"{math.degrees(a):g}" for a in _DEFAULTS["mount_angles_rad"])


@click.command("particle")
@log_argument("STEPS.csv", required=False)
@click.option("--steps", type=click.Path(dir_okay=True), default=None, hidden=True)
@click.option(
    "--map",
    "map_path",
    type=click.Path(dir_okay=True),
    default=None,
    metavar="PLAN.json",
    help=f"The floor plan ({doc_page('floorplan.md')}); needed by --mode model and ranging.",
)
@click.option(
    "--ranges",
    type=click.Path(dir_okay=True),
    default=None,
    metavar="RANGES.csv",
    help=f"Range readings t_s,sensor,range_m (empty = no echo; {doc_page('formats.md')}).",
)
@click.option(
    "--start",
    required=True,
    metavar="X,Y",
    help="The walker's position at the first step, m (Girard 2011 §3.2 step 1).",
)
@click.option(
    "--method",
    type=click.Choice(METHODS),
    default=None,
    help="The paper's filter (κ motion vectors, wall elimination, merging, eq. (1), keep "
    "the ν best) or sequential importance resampling with the SRF02 error model "
    f"{shown_default(_DEFAULTS['method'])}.",
)
@click.option(
    "--mode",
    type=click.Choice(MODES),
    default=None,
    help="Steps only; steps + floor plan; steps + plan + range readings (Girard 2011 "
    "Table 1) [default: ranging with --ranges, else model with --map, else imu].",
)
@click.option(
    "--particles",
    type=click.IntRange(min=1, max=MAX_PARTICLES),
    default=None,
    metavar="N",
    help=f"ν, the number of particles kept, at most {MAX_PARTICLES:,} (memory), and with "
    f"--method girard at most {MAX_CANDIDATES // _DEFAULTS['kappa']:,} (it holds ν κ = "
    f"{_DEFAULTS['kappa']} candidate moves); the paper's 150 "
    f"{shown_default(_DEFAULTS['n_particles'])}.",
)
@click.option(
    "--mounts",
    default=None,
    metavar="DEG[,DEG...]",
    help="Each range sensor's axis relative to the walking direction, degrees, sensor 0 "
    "first; with --rig each tag's lever-arm direction by default "
    f"{shown_default(_MOUNTS_DEG + ': back to back, sensor 0 facing left')}.",
)
@rig_option(
    f"Rig file ({doc_page('rigs.md')}, odometry 'steps'): range sensor s is the rig's s-th tag, "
    "placed at its lever arm and facing away from the body centre (unless --mounts)."
)
@click.option(
    "--seed",
    type=click.IntRange(min=0),
    default=None,
    metavar="S",
    help="Random seed (>= 0); the same seed gives the same track [default: fresh entropy].",
)
@output_options
def particle_cmd(log, steps, map_path, ranges, start, method, mode, particles, mounts, rig,
                 seed, fmt, output):  # fmt: skip
    """A walker's position on a floor plan from foot-mounted-IMU step events and
    body-worn SRF02 range finders (the particle filter of Girard 2011 §3.2, or SIR).

    STEPS.csv is a step log t_s,length_m,heading_rad,heading_sigma_rad (formats.md of the
    documentation).
    Prints t_s, x_m, y_m, n_particles, spread_m per step, a summary on stderr, and each
    re-initialisation (walker left the map, all particles died) as a warning.

    \b
    Examples:
      rangekit track particle steps.csv --map plan.json --ranges ranges.csv \\
          --start 1.25,1 -o track.csv
      rangekit track particle steps.csv --map plan.json --ranges ranges.csv \\
          --start 1.25,1 --method sir --particles 10000 --seed 1
    """
    from rangekit_cli._options import float_list

    from rangekit.errors import InvalidParameterError
    from rangekit.floorplan import load_floorplan
    from rangekit.io.steplog import read_range_log, read_step_log
    from rangekit.localize.particle import default_mode, rig_config, track_particles, track_report

    if log is not None and steps is not None:
        raise click.UsageError("give the step log once: as STEPS.csv or as --steps, not both")
    steps = log if steps is None else steps
    if steps is None:
        raise click.UsageError("track particle needs the step log (STEPS.csv, missing argument)")
    xy0 = float_list(start, name="--start")
    if len(xy0) != 2:
        raise click.BadParameter(
            f"{start!r} must be two numbers X,Y (m), got {len(xy0)}", param_hint="--start"
        )
    if mode is None:
        mode = default_mode(plan=map_path is not None, ranges=ranges is not None)
    if mode in ("model", "ranging") and map_path is None:
        raise click.UsageError(f"--mode {mode} needs --map PLAN.json (the floor plan)")
    if mode == "ranging" and ranges is None:
        raise click.UsageError("--mode ranging needs --ranges RANGES.csv (the range readings)")
    if mode != "ranging" and ranges is not None:
        raise click.UsageError(f"--ranges is not used by --mode {mode} (only by ranging)")
    cfg: dict = {"mode": mode}
    if method is not None:
        cfg["method"] = method
    if particles is not None:
        cfg["n_particles"] = particles
    if mounts is not None:
        cfg["mount_angles_rad"] = tuple(
            math.radians(a) for a in float_list(mounts, name="--mounts", lo=-360.0, hi=360.0)
        )
    try:
        config = ParticleConfig(**cfg)  # the options (exit 2)
    except InvalidParameterError as e:
        if e.param != "n_particles":
            raise
        raise click.BadParameter(str(e), param_hint="--particles") from None
    if rig is not None:  # and how they fit the rig (exit 5, IncompatibleInputError)
        from rangekit.rig import read_rig

        config = rig_config(read_rig(rig), name=str(rig), **cfg)
    slog = read_step_log(steps, name=str(steps))
    rlog = None if ranges is None else read_range_log(ranges, name=str(ranges))
    plan = None if map_path is None else load_floorplan(map_path)
    names = {"plan_name": str(map_path), "ranges_name": str(ranges), "mounts_name": "--mounts",
             "rig_name": None if rig is None else str(rig), "start_name": "--start"}  # fmt: skip
    trk = track_particles(plan, slog, rlog, xy0, config, rng=seed, names=names)
    rep = track_report(trk, log=str(steps), start_xy=xy0, plan=map_path, ranges=ranges,
                       rig=rig, seed=seed)  # fmt: skip
    write_report(rep, fmt, output)
