"""Nothing hangs (issue 17): FIFOs refused unopened, count options bounded, a scheduler
that never answers times out, Ctrl-C on a parallel batch exits 130 with a true count."""

from __future__ import annotations

import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rangekit.batch import find_sessions, run_batch
from rangekit.errors import InputFileError, InvalidParameterError
from rangekit.signals import Beep

ROOT = Path(__file__).resolve().parents[1]
REC = ROOT / "fixtures_audio" / "beepbeep_2p5m.wav"


def test_fifo_recording_and_template_are_refused_unopened(tmp_path):
    from rangekit.io.audio import open_audio, read_audio
    from rangekit.signals.probe import read_probe

    fifo = tmp_path / "f.wav"
    os.mkfifo(fifo)
    for fn in (read_audio, open_audio, read_probe):
        with pytest.raises(InputFileError, match=r"f\.wav': it is a FIFO"):
            fn(fifo)


def test_beep_counts_are_bounded():
    with pytest.raises(InvalidParameterError, match=r"n_bursts=100000000 must be <= 64"):
        Beep(n_bursts=100_000_000)
    with pytest.raises(InvalidParameterError, match=r"more than 10 s"):
        Beep(n_bursts=64, spacing=10**6)
    assert Beep(n_bursts=64).n_bursts == 64


def test_cli_count_options_say_their_bound():
    from clihelp import run

    r = run(["range", "--help"])
    assert "at most 64" in r.stdout
    r = run(["range", "x.wav", "--bursts", "100000000"])
    assert r.exit_code == 2 and "--bursts" in r.stderr
    r = run(["experiment", "ahn2007", "--trials", "100001"])
    assert r.exit_code == 2 and "--trials" in r.stderr
    assert "1 to 10000" in run(["experiment", "--help"]).stdout


sys.path.insert(0, str(ROOT / "tests" / "cli"))


@pytest.mark.parametrize("address", ["tcp://", "tcp://host", "http://x:1", "tcp://h:99999"])
def test_malformed_scheduler_address_is_a_usage_error(tmp_path, address):
    pytest.importorskip("distributed")
    shutil.copy(REC, tmp_path / "r.wav")
    with pytest.raises(InvalidParameterError, match="not an address"):
        run_batch(find_sessions([tmp_path]), tmp_path / "x.csv", scheduler=address)


def test_scheduler_that_accepts_and_never_answers_times_out(tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    import rangekit.batch

    monkeypatch.setattr(rangekit.batch, "DASK_CONNECT_TIMEOUT_S", 1.0)
    shutil.copy(REC, tmp_path / "r.wav")
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)  # the kernel accepts; nobody ever answers
    port = srv.getsockname()[1]
    try:
        with pytest.raises(InputFileError, match=rf"127\.0\.0\.1:{port}"):
            run_batch(
                find_sessions([tmp_path]), tmp_path / "x.csv", scheduler=f"tcp://127.0.0.1:{port}"
            )
    finally:
        srv.close()


@pytest.mark.skipif(sys.platform != "linux", reason="signals as on Linux")
def test_ctrl_c_on_parallel_batch_exits_130_with_the_true_count(tmp_path):
    arch = tmp_path / "a"
    arch.mkdir()
    for i in range(40):
        shutil.copy(REC, arch / f"s{i:02d}.wav")
    out = tmp_path / "r.csv"
    cmd = [sys.executable, "-m", "rangekit", "batch", str(arch), "-o", str(out)]
    for quiet in (["-q"], []):
        out.unlink(missing_ok=True)
        p = subprocess.Popen(
            [*cmd, "--jobs", "2", *quiet], stderr=subprocess.PIPE, stdout=subprocess.PIPE
        )
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and p.poll() is None:
            if out.exists() and out.read_text().count("\n") >= 3:  # header + 2 sessions
                break
            time.sleep(0.05)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
        err = err.decode()
        if p.returncode == 0:
            pytest.skip("the batch finished before the interrupt")
        assert p.returncode == 130, err
        assert "Traceback" not in err and "internal error" not in err
        n = sum(1 for ln in out.read_text().splitlines()[1:] if ln)
        assert f"interrupted: {n} of 40 sessions are in" in err, (n, err)


def test_library_arguments_raise_only_rangekit_errors():
    import numpy as np

    from rangekit.detect import detect_changepoint, detect_xcorr
    from rangekit.errors import InvalidParameterError

    x = np.zeros(5000)
    for kw in ({"win_s": math.nan}, {"threshold_db": 1e6}, {"expected": 0}, {"hop_s": -1}):
        with pytest.raises(InvalidParameterError, match=next(iter(kw))):
            detect_changepoint(x, fs=44100.0, **kw)
    for kw in ({"threshold_db": math.nan}, {"threshold_db": 1e6}, {"min_confidence": 2}):
        with pytest.raises(InvalidParameterError, match=next(iter(kw))):
            detect_xcorr(x, fs=44100.0, **kw)
    for bad in (np.zeros((2, 100)), "abc", np.r_[x, 1e300], x.astype(complex) + 1j):
        with pytest.raises(InvalidParameterError, match="x "):
            detect_changepoint(bad, fs=44100.0)


def test_a_1e300_sample_in_a_float_wav_is_refused(tmp_path):
    import numpy as np
    import soundfile as sf
    from clihelp import assert_error, run

    x = np.zeros((44100, 2))
    x[100, 0] = 1e300
    sf.write(tmp_path / "big.wav", x, 44100, subtype="DOUBLE")
    assert_error(run(["range", tmp_path / "big.wav"]), 4, "big.wav", "magnitude 1e+300")


def test_memory_budget_refuses_whole_file_reads_with_a_hint(tmp_path, monkeypatch):
    from clihelp import assert_error, ok, run

    from rangekit.io.audio import BUDGET_ENV, read_audio

    # a sparse WAV whose header promises 2 GiB of 16-bit stereo samples
    p = tmp_path / "sparse.wav"
    data = 2**31
    hdr = b"RIFF" + (36 + data).to_bytes(4, "little") + b"WAVEfmt "
    hdr += (16).to_bytes(4, "little") + (1).to_bytes(2, "little") + (2).to_bytes(2, "little")
    hdr += (44100).to_bytes(4, "little") + (44100 * 4).to_bytes(4, "little")
    hdr += (4).to_bytes(2, "little") + (16).to_bytes(2, "little")
    hdr += b"data" + data.to_bytes(4, "little")
    with open(p, "wb") as f:
        f.write(hdr)
        f.truncate(len(hdr) + data)
    monkeypatch.setenv(BUDGET_ENV, "1G")
    with pytest.raises(Exception, match=r"sparse\.wav'.*--series") as e:
        read_audio(p)
    assert e.value.exit_code == 5
    line = assert_error(run(["range", p]), 5, "sparse.wav", "memory budget of 1.00 GiB")
    assert "--series" in line and "--memory-budget" in line
    monkeypatch.delenv(BUDGET_ENV)
    assert_error(run(["--memory-budget", "1M", "range", REC]), 5, "memory budget of 1.0 MiB")
    ok(run(["--memory-budget", "off", "range", REC]))
    assert_error(run(["--memory-budget", "lots", "range", REC]), 2, "--memory-budget")


def test_echo_recording_shorter_than_one_period_is_exit_5(tmp_path):
    import numpy as np
    from clihelp import assert_error, run

    from rangekit.io.audio import write_audio

    write_audio(tmp_path / "e.wav", np.zeros(1000), fs=192000.0)
    r = run(["range", "--scheme", "echo", tmp_path / "e.wav", "--period", "1"])
    assert_error(r, 5, "e.wav", "shorter than one window of --period 1 s")
    os.mkfifo(tmp_path / "p.wav")
    r = run(["range", "--scheme", "echo", tmp_path / "p.wav", "--period", "1"])
    assert_error(r, 3, "p.wav", "FIFO")


class _Fut:
    def __init__(self, rows=None, error=None):
        self.rows, self.error = rows, error

    def result(self):
        if self.error is not None:
            raise self.error
        return self.rows


class _Client:
    def __init__(self, workers):
        self.workers = workers

    def scheduler_info(self):
        if isinstance(self.workers, Exception):
            raise self.workers
        return {"workers": self.workers}


def test_dask_watchdog_stops_when_workers_die_or_a_task_is_killed():
    from rangekit.batch import _dask_watch

    got = []
    ok_fut, stuck = _Fut([["r1"], ["r2"]]), _Fut()
    calls = []

    def wait(pending, timeout, return_when):
        calls.append(len(pending))
        if ok_fut in pending:
            return {ok_fut}, pending - {ok_fut}
        raise TimeoutError

    for workers, why in [({}, "has no worker left: 1 task"), (OSError("gone"), "lost the Dask")]:
        got.clear()
        with pytest.raises(InputFileError, match=why) as e:
            _dask_watch(_Client(workers), [ok_fut, stuck], got.append, address="h:1", wait=wait)
        assert got == [["r1"], ["r2"]] and "--resume" in str(e.value)
    killed = _Fut(error=RuntimeError("KilledWorker: worker died 3 times"))
    with pytest.raises(InputFileError, match=r"a task failed on .*KilledWorker"):
        _dask_watch(
            _Client({"w": 1}),
            [killed],
            got.append,
            address="tcp://h:1",
            wait=lambda p, timeout, return_when: (set(p), set()),
        )
