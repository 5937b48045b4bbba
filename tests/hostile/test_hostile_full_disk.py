"""A real short write while training is one line (issue 57, class 5): the child process runs under a
file size limit (``RLIMIT_FSIZE``, with ``SIGXFSZ`` ignored so that a write past it fails with EFBIG as
on a full disk), so ``torch.save`` meets a real failed write, not a patched one."""

from __future__ import annotations

import resource
import signal
import subprocess
import sys

import pytest
import torch
from helpers import CLI_ENV, QUIET, TINY_1V1, cli_cmd

from volleybots.config import ConfigError
from volleybots.files import write_atomic

LIMIT = 16_000  # bytes: past config.yaml and metrics.csv of a tiny run, short of its checkpoint


def _limited():
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))


def test_training_past_a_file_size_limit_is_one_line_and_leaves_no_temporary_file(tmp_path):
    # (wider networks than the tiny run's: torch.save then fails in a record's header, where it raised
    # its own RuntimeError; with [16] it happened to fail where the OSError came through)
    run = tmp_path / "run"
    res = subprocess.run(cli_cmd("train", *TINY_1V1, *QUIET, "algo=mappo", "algo.hidden=[256,256]", "total_frames=128",
                                 f"hydra.run.dir={run}"),
                         env=CLI_ENV, capture_output=True, text=True, timeout=600, preexec_fn=_limited)
    err = res.stderr.strip()
    assert res.returncode == 2, (res.returncode, err[-2000:])
    assert len(err.splitlines()) == 1 and err.startswith("error: cannot write a checkpoint"), err
    assert "File too large" in err and "Traceback" not in err and "inline_container" not in err
    assert not list(run.rglob("*.tmp")) and (run / "config.yaml").is_file()


def test_write_atomic_says_what_torch_save_met(tmp_path):
    code = (
        "import resource, signal, torch\n"
        "from volleybots.files import write_atomic\n"
        "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
        f"resource.setrlimit(resource.RLIMIT_FSIZE, ({LIMIT}, {LIMIT}))\n"
        f"write_atomic({str(tmp_path / 'x.pt')!r}, lambda f: torch.save(torch.zeros(100_000), f), 'a checkpoint')\n"
    )
    res = subprocess.run([sys.executable, "-c", code], env=CLI_ENV, capture_output=True, text=True, timeout=120)
    assert res.returncode == 1 and "ConfigError: cannot write a checkpoint" in res.stderr and "File too large" in res.stderr, res.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_writer_error_that_is_no_disk_error_is_left_as_it_is(tmp_path):
    def broken(f):
        raise RuntimeError("a bug in the writer")

    with pytest.raises(RuntimeError, match="a bug in the writer"):
        write_atomic(tmp_path / "x.pt", broken)
    write_atomic(tmp_path / "ok.pt", lambda f: torch.save({"a": 1}, f))
    assert torch.load(tmp_path / "ok.pt") == {"a": 1} and [p.name for p in tmp_path.iterdir()] == ["ok.pt"]
    with pytest.raises(ConfigError):
        write_atomic(tmp_path / "missing" / "x.pt", "text")
