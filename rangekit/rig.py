"""Rig descriptions: fixed anchors, the tracked body's tags, its odometry (``docs/rigs.md``).

A *rig* says what a user's tracking setup is, once, in a JSON file: the fixed anchors
(beacons, UWB anchors, ceiling transmitters) with their positions and optionally a known
range bias and 1-sigma each; the receivers or tags carried by the tracked body with their
lever arms in the body frame (x forward, y left; any number, one at the centre included);
and the body's odometry (differential drive with its wheel base, step events, or none).
The range trackers read it (:mod:`rangekit.localize.anchor_ekf`, ``rangekit track --rig``);
the papers' rigs ship as examples in ``docs/rigs/``.

Examples
--------
>>> doc = {"format": "rangekit-rig", "version": 1, "units": "m",
...        "anchors": [{"id": 1, "x_m": 0.0, "y_m": 0.0},
...                    {"id": 2, "x_m": 2.4, "y_m": 0.0, "bias_m": 0.05}],
...        "body": {"tags": [{"id": 1}]},
...        "odometry": {"type": "differential-drive", "wheel_base_m": 0.33}}
>>> rig = parse_rig(doc, name="rig.json")
>>> rig.anchor_ids.tolist(), rig.anchor_bias_m.tolist(), rig.tag_lever_m.tolist()
([1, 2], [0.0, 0.05], [[0.0, 0.0, 0.0]])
>>> rig.odometry.kind, rig.odometry.wheel_base_m
('differential-drive', 0.33)
>>> parse_rig({**doc, "body": {"tags": []}}, name="rig.json")
Traceback (most recent call last):
...
rangekit.errors.InvalidParameterError: rig.json: body.tags: needs at least one tag
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from rangekit._jsondoc import check_header, json_number
from rangekit.errors import IncompatibleInputError, InputFileError, InvalidParameterError

__all__ = [
    "RIG_FORMAT",
    "RIG_VERSION",
    "Odometry",
    "Rig",
    "parse_rig",
    "read_rig",
]

#: Value of the ``"format"`` key of a rig document.
RIG_FORMAT = "rangekit-rig"
#: Rig format version this module reads and writes.
RIG_VERSION = 1

ODOMETRY_KINDS = ("differential-drive", "steps", "none")

#: Default 1-sigma of a range when neither the anchor nor ``ranges`` gives one (m).
DEFAULT_SIGMA_M = 0.10
#: Default prior 1-sigma of the range bias common to every anchor (m).
DEFAULT_COMMON_BIAS_SIGMA_M = 0.20
#: Default prior 1-sigma of each anchor's own range bias (m).
DEFAULT_BIAS_SIGMA_M = 0.05

_TOP = {"format", "version", "units", "name", "notes", "anchors", "body", "odometry", "ranges"}
_ANCHOR = {"id", "x_m", "y_m", "z_m", "bias_m", "sigma_m", "bias_sigma_m"}
_TAG = {"id", "x_m", "y_m", "z_m", "axis_deg"}
_ODO = {
    "differential-drive": {"type", "wheel_base_m", "k_v_m"},
    "steps": {"type", "length_sigma_m", "heading_sigma_rad"},
    "none": {"type", "accel_psd"},
}
_RANGES = {"sigma_m", "bias_sigma_m", "common_bias_sigma_m", "estimate_bias"}


@dataclass(frozen=True)
class Odometry:
    """How the tracked body reports its own motion.

    Attributes
    ----------
    kind : {"differential-drive", "steps", "none"}
    wheel_base_m : float
        Distance between the drive wheels (differential drive; Kim & Kim 2013 eq (14) B_w).
    k_v_m : float
        Wheel-velocity noise coefficient, variance ``k_v |v| / Δt`` (Kim & Kim 2013 §V,
        default 4e-4 m).
    accel_psd : float
        ``none``: spectral density of the body's white acceleration (m²/s³, constant
        velocity model of Jiang 2018 eqs (2)–(3)); default 0.05.
    length_sigma_m : float
        ``steps``: 1-sigma of a step's length (m, default 0.05).
    heading_sigma_rad : float
        ``steps``: 1-sigma of a step's heading where the step log leaves it empty (rad,
        default 0.1).
    """

    kind: str
    wheel_base_m: float = float("nan")
    k_v_m: float = 4e-4
    accel_psd: float = 0.05
    length_sigma_m: float = 0.05
    heading_sigma_rad: float = 0.1


@dataclass(frozen=True)
class Rig:
    """A parsed rig (see the module docstring and ``docs/rigs.md``).

    Attributes
    ----------
    anchor_ids : ndarray of int, shape (A,)
    anchor_xyz_m : ndarray, shape (A, 3)
        Anchor positions (z default 0).
    anchor_bias_m : ndarray, shape (A,)
        Known (or prior mean) range bias of each anchor: measured = true + bias (m).
    anchor_sigma_m : ndarray, shape (A,)
        1-sigma of one range from that anchor (m).
    anchor_bias_sigma_m : ndarray, shape (A,)
        Prior 1-sigma of each anchor's own unknown bias (m); 0: the bias is known.
    common_bias_sigma_m : float
        Prior 1-sigma of an unknown bias shared by every anchor (m): the prior covariance
        of the biases is ``σ_c² 1 1ᵀ + diag(σ_i²)``.
    tag_ids : ndarray of int, shape (T,)
    tag_lever_m : ndarray, shape (T, 3)
        Tag positions in the body frame (x forward, y left, z up), m.
    tag_axis_rad : ndarray, shape (T,)
        Each tag's pointing axis in the body frame (rad from forward, counter-clockwise:
        ``axis_deg`` in the file), NaN where the file gives none. Directional sensors (an
        SRF02 range finder) need it; omnidirectional tags (UWB, microphones) do not.
    odometry : Odometry
    name : str
    """

    anchor_ids: np.ndarray
    anchor_xyz_m: np.ndarray
    anchor_bias_m: np.ndarray
    anchor_sigma_m: np.ndarray
    anchor_bias_sigma_m: np.ndarray
    tag_ids: np.ndarray
    tag_lever_m: np.ndarray
    odometry: Odometry
    name: str = ""
    common_bias_sigma_m: float = 0.0
    tag_axis_rad: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.tag_axis_rad is None:
            object.__setattr__(self, "tag_axis_rad", np.full(self.tag_ids.size, np.nan))

    @property
    def n_anchors(self) -> int:
        return int(self.anchor_ids.size)

    @property
    def n_tags(self) -> int:
        return int(self.tag_ids.size)

    def require_anchors(self, what: str, *, source: str = "the rig") -> None:
        """Refuse a rig without anchors for ``what`` (a tracker that ranges anchors):
        :class:`~rangekit.errors.IncompatibleInputError` naming ``source`` (its file)."""
        if self.n_anchors == 0:
            raise IncompatibleInputError(
                f"{source}: {what} ranges fixed anchors, and the rig has none"
            )

    def anchor_index(self, anchor_id: int) -> int:
        """Row of anchor ``anchor_id`` (InvalidParameterError if it is not in the rig)."""
        hit = np.flatnonzero(self.anchor_ids == int(anchor_id))
        if hit.size == 0:
            raise InvalidParameterError(
                f"anchor {anchor_id} is not in the rig (ids: {self.anchor_ids.tolist()})"
            )
        return int(hit[0])

    def to_json(self) -> dict[str, Any]:
        """The rig as a JSON-ready dict (round-trips through :func:`parse_rig`)."""
        odo: dict[str, Any] = {"type": self.odometry.kind}
        if self.odometry.kind == "differential-drive":
            odo |= {"wheel_base_m": self.odometry.wheel_base_m, "k_v_m": self.odometry.k_v_m}
        elif self.odometry.kind == "none":
            odo["accel_psd"] = self.odometry.accel_psd
        else:
            odo["length_sigma_m"] = self.odometry.length_sigma_m
            odo["heading_sigma_rad"] = self.odometry.heading_sigma_rad
        return {
            "format": RIG_FORMAT,
            "version": RIG_VERSION,
            "units": "m",
            "name": self.name,
            "anchors": [
                {
                    "id": int(i),
                    "x_m": float(p[0]),
                    "y_m": float(p[1]),
                    "z_m": float(p[2]),
                    "bias_m": float(b),
                    "sigma_m": float(s),
                    "bias_sigma_m": float(bs),
                }
                for i, p, b, s, bs in zip(
                    self.anchor_ids,
                    self.anchor_xyz_m,
                    self.anchor_bias_m,
                    self.anchor_sigma_m,
                    self.anchor_bias_sigma_m,
                    strict=True,
                )
            ],
            "body": {
                "tags": [
                    {"id": int(i), "x_m": float(p[0]), "y_m": float(p[1]), "z_m": float(p[2])}
                    | ({} if np.isnan(a) else {"axis_deg": float(np.degrees(a))})
                    for i, p, a in zip(
                        self.tag_ids, self.tag_lever_m, self.tag_axis_rad, strict=True
                    )
                ]
            },
            "odometry": odo,
            "ranges": {"common_bias_sigma_m": self.common_bias_sigma_m},
        }


def _obj(where: str, v: Any, keys: set[str], required: tuple[str, ...]) -> Mapping:
    if not isinstance(v, Mapping):
        raise InvalidParameterError(f"{where}: must be a JSON object, got {type(v).__name__}")
    for k in required:
        if k not in v:
            raise InvalidParameterError(f"{where}: missing key {k!r}")
    extra = sorted(set(v) - keys)
    if extra:
        raise InvalidParameterError(f"{where}: unknown key {extra[0]!r} (known: {sorted(keys)})")
    return v


def _int_id(where: str, v: Any) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
        raise InvalidParameterError(f"{where}.id={v!r} must be an integer >= 0")
    return int(v)


def _pos(where: str, v: Any, *, strict: bool = False) -> float:
    f = json_number(where, v)
    if f < 0 or (strict and f == 0):
        raise InvalidParameterError(f"{where}={v!r} must be {'> 0' if strict else '>= 0'}")
    return f


def _parse(obj: Any) -> Rig:
    check_header(
        obj, what="a rig file", fmt=RIG_FORMAT, version=RIG_VERSION, body="body", allowed=_TOP
    )
    for k in ("body", "odometry"):
        if k not in obj:
            raise InvalidParameterError(f"missing key {k!r}")
    rng = _obj("ranges", obj.get("ranges", {}), _RANGES, ())
    sigma0 = _pos("ranges.sigma_m", rng.get("sigma_m", DEFAULT_SIGMA_M), strict=True)
    bsig0 = _pos("ranges.bias_sigma_m", rng.get("bias_sigma_m", DEFAULT_BIAS_SIGMA_M))
    csig = _pos(
        "ranges.common_bias_sigma_m", rng.get("common_bias_sigma_m", DEFAULT_COMMON_BIAS_SIGMA_M)
    )
    est = rng.get("estimate_bias", True)
    if not isinstance(est, bool):
        raise InvalidParameterError(f"ranges.estimate_bias={est!r} must be true or false")
    if not est:
        csig = 0.0
    anchors = obj.get("anchors", [])
    if not isinstance(anchors, list):
        raise InvalidParameterError("anchors: must be a list of anchors")
    ids, xyz, bias, sig, bsig, seen = [], [], [], [], [], {}
    for i, a in enumerate(anchors):
        w = f"anchors[{i}]"
        a = _obj(w, a, _ANCHOR, ("id", "x_m", "y_m"))
        aid = _int_id(w, a["id"])
        if aid in seen:
            raise InvalidParameterError(f"{w}.id={aid} repeats anchors[{seen[aid]}].id")
        seen[aid] = i
        ids.append(aid)
        xyz.append([json_number(f"{w}.{k}", a.get(k, 0.0)) for k in ("x_m", "y_m", "z_m")])
        bias.append(json_number(f"{w}.bias_m", a.get("bias_m", 0.0)))
        sig.append(_pos(f"{w}.sigma_m", a.get("sigma_m", sigma0), strict=True))
        bsig.append(_pos(f"{w}.bias_sigma_m", a.get("bias_sigma_m", bsig0 if est else 0.0)))
    body = _obj("body", obj["body"], {"tags", "name"}, ("tags",))
    tags = body["tags"]
    if not isinstance(tags, list):
        raise InvalidParameterError("body.tags: must be a list of tags")
    if not tags:
        raise InvalidParameterError("body.tags: needs at least one tag")
    tids, lever, axis, tseen = [], [], [], {}
    for i, t in enumerate(tags):
        w = f"body.tags[{i}]"
        t = _obj(w, t, _TAG, ("id",))
        tid = _int_id(w, t["id"])
        if tid in tseen:
            raise InvalidParameterError(f"{w}.id={tid} repeats body.tags[{tseen[tid]}].id")
        tseen[tid] = i
        tids.append(tid)
        lever.append([json_number(f"{w}.{k}", t.get(k, 0.0)) for k in ("x_m", "y_m", "z_m")])
        a = json_number(f"{w}.axis_deg", t["axis_deg"]) if "axis_deg" in t else float("nan")
        if abs(a) > 360.0:
            raise InvalidParameterError(f"{w}.axis_deg={a!r} must be within -360..360")
        axis.append(np.radians(a))
    od = obj["odometry"]
    if not isinstance(od, Mapping) or "type" not in od:
        raise InvalidParameterError("odometry: missing key 'type'")
    kind = od["type"]
    if kind not in ODOMETRY_KINDS:
        raise InvalidParameterError(
            f"odometry.type={kind!r} must be one of {', '.join(map(repr, ODOMETRY_KINDS))}"
        )
    _obj("odometry", od, _ODO[kind], ("wheel_base_m",) if kind == "differential-drive" else ())
    if kind == "differential-drive":
        odo = Odometry(
            kind,
            wheel_base_m=_pos("odometry.wheel_base_m", od["wheel_base_m"], strict=True),
            k_v_m=_pos("odometry.k_v_m", od.get("k_v_m", 4e-4)),
        )
    elif kind == "none":
        odo = Odometry(
            kind, accel_psd=_pos("odometry.accel_psd", od.get("accel_psd", 0.05), strict=True)
        )
    else:
        odo = Odometry(
            kind,
            length_sigma_m=_pos("odometry.length_sigma_m", od.get("length_sigma_m", 0.05)),
            heading_sigma_rad=_pos("odometry.heading_sigma_rad", od.get("heading_sigma_rad", 0.1)),
        )
    name = obj.get("name", "")
    return Rig(
        np.array(ids, dtype=np.int64),
        np.array(xyz, dtype=np.float64).reshape(-1, 3),  # (0, 3) without anchors
        np.array(bias, dtype=np.float64),
        np.array(sig, dtype=np.float64),
        np.array(bsig, dtype=np.float64),
        np.array(tids, dtype=np.int64),
        np.array(lever, dtype=np.float64),
        odo,
        str(name),
        csig,
        np.array(axis, dtype=np.float64).reshape(-1),
    )


def parse_rig(obj: Any, *, name: str = "<rig>") -> Rig:
    """Build a :class:`Rig` from a parsed rig JSON document (format in ``docs/rigs.md``).

    Raises
    ------
    InvalidParameterError
        ``"{name}: {field}: {problem}"`` for the first problem: a missing or unknown key,
        another format, version or unit, an empty tag list, a repeated id, a
        coordinate that is not a finite number, a sigma or wheel base <= 0, an unknown
        odometry type.
    """
    try:
        return _parse(obj)
    except InvalidParameterError as e:
        raise InvalidParameterError(f"{name}: {e}") from None


def read_rig(path: str | os.PathLike) -> Rig:
    """Read and validate a rig JSON file.

    Raises
    ------
    InputFileError
        Missing file, not JSON, or not a valid rig; one line naming the file and the
        field (``'rig.json' is not a valid rig file: anchors[2]: missing key 'y_m'``).
    """
    from rangekit.io.sidecar import read_json

    obj = read_json(path)
    try:
        return _parse(obj)
    except InvalidParameterError as e:
        raise InputFileError(f"'{os.fspath(path)}' is not a valid rig file: {e}") from e
