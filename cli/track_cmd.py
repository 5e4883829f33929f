"""``rangekit track``: a group with one subcommand per tracking filter.

Each subcommand lives in its own module (``track_range_ekf``, ``track_fixes``,
``track_duhl``, ``track_particle``) and is imported only when used; the options they
share are in ``track_common``. The old form ``rangekit track --filter NAME ...`` still
works for one release (hidden; a deprecation line on stderr after the results).
"""

from __future__ import annotations

import click

#: Subcommand -> (module, attribute, one-line help shown by ``rangekit track --help``).
SUBCOMMANDS: dict[str, tuple[str, str, str]] = {
    "range-ekf": (
        "rangekit_cli.track_range_ekf",
        "range_ekf_cmd",
        "People from acoustic ranges (Jiang 2018); a body against a rig's anchors (--rig).",
    ),
    "dead-reckoning": (
        "rangekit_cli.track_fixes",
        "dead_reckoning_cmd",
        "A robot from accelerometer + odometer, with bias states (Ahn & Yu 2007).",
    ),
    "lmax": (
        "rangekit_cli.track_fixes",
        "lmax_cmd",
        "A pedestrian's position fixes through the l_max filter (Ahn & Yu 2007).",
    ),
    "duhl": (
        "rangekit_cli.track_duhl",
        "duhl_cmd",
        "A robot's pose from wheel odometry and ceiling ultrasonic beacons (Kim & Kim 2013).",
    ),
    "duhl-ranges": (
        "rangekit_cli.track_duhl",
        "duhl_ranges_cmd",
        "The same, each beacon's distances fed straight to the EKF (no UHL).",
    ),
    "particle": (
        "rangekit_cli.track_particle",
        "particle_cmd",
        "A walker on a floor plan from steps and range finders (Girard 2011).",
    ),
}

#: The deprecation line of ``rangekit track --filter NAME`` (printed after the results).
DEPRECATED = (
    "rangekit: warning: 'rangekit track --filter {name}' is deprecated and will be removed "
    "in the next release; use 'rangekit track {name}'"
)


class TrackGroup(click.Group):
    """Subcommands imported when used; ``--filter NAME`` rewritten to ``NAME``."""

    def list_commands(self, ctx):
        return list(SUBCOMMANDS)

    def get_command(self, ctx, name):
        if name not in SUBCOMMANDS:
            return None
        import importlib

        mod, attr, _ = SUBCOMMANDS[name]
        return getattr(importlib.import_module(mod), attr)

    def format_commands(self, ctx, formatter):
        """The subcommand list from :data:`SUBCOMMANDS` (no module imported for help)."""
        with formatter.section("Commands"):
            formatter.write_dl([(n, h) for n, (_, _, h) in SUBCOMMANDS.items()])

    def parse_args(self, ctx, args):
        args = _rewrite_filter(ctx, list(args))
        return super().parse_args(ctx, args)

    def resolve_command(self, ctx, args):
        name = args[0] if args else ""
        if name not in SUBCOMMANDS and not name.startswith("-"):
            raise click.UsageError(
                f"no tracking filter {name!r}: the first argument is the filter, one of "
                f"{', '.join(SUBCOMMANDS)} (e.g. 'rangekit track range-ekf LOG.csv')",
                ctx=ctx,
            )
        return super().resolve_command(ctx, args)


def _rewrite_filter(ctx: click.Context, args: list[str]) -> list[str]:
    """``... --filter NAME ...`` (or ``--filter=NAME``) as ``NAME ...``; notes the deprecation."""
    for i, a in enumerate(args):
        if a == "--":
            break
        if a == "--filter" or a.startswith("--filter="):
            if a == "--filter":
                if i + 1 >= len(args):
                    raise click.UsageError("--filter needs a filter name", ctx=ctx)
                name, rest = args[i + 1], args[:i] + args[i + 2 :]
            else:
                name, rest = a.split("=", 1)[1], args[:i] + args[i + 1 :]
            if name not in SUBCOMMANDS:
                raise click.UsageError(
                    f"--filter {name!r} is not one of {', '.join(SUBCOMMANDS)}", ctx=ctx
                )
            notes = ctx.meta.setdefault("rangekit.notes", [])
            notes.append(DEPRECATED.format(name=name))
            return [name, *rest]
    return args


@click.group("track", cls=TrackGroup, no_args_is_help=True)
def track_cmd():
    """Track from a log: people from ranges, a robot from its IMU or beacons, a walker's
    fixes or steps. One subcommand per filter, each with its own options
    ('rangekit track FILTER --help').

    Each prints the track as CSV (one row per epoch) or JSON ("columns" and "rows"),
    and a one-line summary on stderr. Log formats: formats.md of the documentation.

    \b
    Examples:
      rangekit track range-ekf walk.csv --smooth -o track.csv
      rangekit track dead-reckoning imu.csv --format json
      rangekit track lmax fixes.csv --l-max 0.5 --i-star 1
      rangekit track duhl run.csv --beacons beacons.json -o pose.csv
      rangekit track particle steps.csv --map plan.json --ranges ranges.csv \\
          --start 1.25,1 -o track.csv
    """
