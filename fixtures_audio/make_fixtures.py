"""Regenerate the audio fixtures in this folder (seeded, reproducible).

Run from the repository root:  python fixtures_audio/make_fixtures.py

Each fixture is a 16-bit PCM WAV with a JSON sidecar holding the ground truth
(the format of ``rangekit synth``; see docs/formats.md). Every file stays under 1 MB.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from rangekit.io.audio import write_audio
from rangekit.io.sidecar import write_json
from rangekit.sim import Device, ShoeboxRoom, pair_devices, render_beepbeep


def _write(name: str, sim, *, seed: int, note: str, mono: bool = False) -> None:
    truth = {**sim.truth, "seed": seed, "note": note}
    if mono:
        files = []
        for i, (x, fs) in enumerate(zip(sim.recordings, sim.fs, strict=True)):
            f = HERE / f"{name}_dev{i}.wav"
            write_audio(f, x, fs=fs)
            files.append(f.name)
    else:
        n = min(len(x) for x in sim.recordings)
        write_audio(
            HERE / f"{name}.wav", np.stack([x[:n] for x in sim.recordings], 1), fs=sim.fs[0]
        )
        files = [f"{name}.wav"]
    truth["files"] = files
    write_json(HERE / f"{name}.json", truth)
    for f in files:
        size = (HERE / f).stat().st_size
        assert size < 1_000_000, f"{f} is {size} bytes"
        print(f"{f}: {size / 1e3:.0f} kB")


def main() -> None:
    # The README default: two phones 2.5 m apart, SNR 20 dB, free field.
    seed = 1
    rng = np.random.default_rng(seed)
    devs = pair_devices(2.5, self_distance_m=0.1, rec_start_s=(0.03, 0.08), clock_ppm=(12.0, -7.0))
    sim = render_beepbeep(devs, snr_db=20, rng=rng)
    _write("beepbeep_2p5m", sim, seed=seed, note="README default: 2 devices, 2.5 m, SNR 20 dB")

    # Reflections: a 6 x 5 x 3 m room, absorption 0.3, first order, 4.2 m apart.
    seed = 2
    rng = np.random.default_rng(seed)
    room = ShoeboxRoom((6.0, 5.0, 3.0), absorption=0.3, max_order=1)
    devs = pair_devices(
        4.2, self_distance_m=0.12, center_m=(3.0, 2.5, 1.2), azimuth_rad=0.5,
        rec_start_s=(0.0, 0.05),
    )  # fmt: skip
    sim = render_beepbeep(devs, snr_db=15, room=room, rng=rng)
    _write("beepbeep_room_4p2m", sim, seed=seed, note="6x5x3 m room, absorption 0.3, SNR 15 dB")

    # Three devices, one mono WAV each, one of them at 48 kHz.
    seed = 3
    rng = np.random.default_rng(seed)
    pts = [np.array(p) for p in ((0.0, 0.0, 1.2), (3.0, 0.5, 1.0), (1.0, 2.5, 1.4))]
    up = np.array([0.0, 0.0, 0.05])
    devs = [
        Device(p - up, p + up, rec_start_s=0.02 * i, clock_ppm=ppm, fs=fs)
        for i, (p, ppm, fs) in enumerate(
            zip(pts, (0.0, 20.0, -15.0), (44100.0, 48000.0, 44100.0), strict=True)
        )
    ]
    sim = render_beepbeep(devs, snr_db=20, rng=rng)
    _write(
        "beepbeep_3dev", sim, seed=seed, note="3 devices, mono files, device 1 at 48 kHz", mono=True
    )


if __name__ == "__main__":
    main()
