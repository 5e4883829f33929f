"""``rangekit range``: the setup sidecar's values for the options not given
(:func:`rangekit.io.setup.find_setup`, :func:`rangekit.io.setup.setup_defaults`)."""

from __future__ import annotations

from rangekit_cli._options import detail, note_after
from rangekit_cli.range_options import given


def apply_setup(files, scheme, self_distance, temp_c, speed, cal, kw):
    """Options not given, from the setup of a sidecar that names exactly ``files``
    (:func:`rangekit.io.setup.find_setup`, :func:`~rangekit.io.setup.setup_defaults`);
    says on stderr what it took. Returns the self-distance and temperature to use; fills
    ``kw`` (period, latency, tx order)."""
    from rangekit.io.guard import is_stdin
    from rangekit.io.setup import find_setup, setup_defaults

    if any(is_stdin(f) for f in files):
        detail("rangekit: setup: not searched for standard input (-)")
        if scheme == "beepbeep" and cal is None and not given("self_distance"):
            note_after(
                "rangekit: standard input: no sidecar setup is read for -, so the "
                "self-distance is 0 m (give --self-distance)"
            )
        return self_distance, temp_c
    setup = find_setup(files)
    if setup is None:
        detail("rangekit: setup: no sidecar beside the recordings names exactly them")
        return self_distance, temp_c
    if setup.scheme != scheme:
        detail(f"rangekit: setup: '{setup.path}' is for --scheme {setup.scheme}, not used")
        return self_distance, temp_c
    unset = {k for k in ("period", "latency", "tx_order") if kw.get(k) is None}
    unset = {k + "_s" if k != "tx_order" else k for k in unset}
    if not given("self_distance") and cal is None:
        unset.add("self_distance_m")
    if not given("temp_c") and speed is None:
        unset.add("temp_c")
    took = []
    for key, value in setup_defaults(setup, scheme, unset).items():
        if key == "self_distance_m":
            self_distance = ",".join(repr(v) for v in value)
            took.append("--self-distance " + ",".join(f"{v:g}" for v in value))
        elif key == "temp_c":
            temp_c = value
            took.append(f"--temperature {value:g}")
        elif key == "tx_order":
            kw["tx_order"] = ",".join(str(t) for t in value)
            took.append(f"--tx-order {kw['tx_order']}")
        else:
            kw[key[:-2]] = value
            took.append(f"--{key[:-2]} {value:g}")
    if took:
        # Said after the results (an error stays one line): rangekit_cli.main prints notes.
        note_after(
            f"rangekit: used the setup in '{setup.path}': {' '.join(took)} (--no-setup to "
            "ignore it)"
        )
    return self_distance, temp_c
