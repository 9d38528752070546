"""Choosing where work runs: the local pool's start method, and Ray only when asked for."""

from __future__ import annotations

import subprocess
import sys

import pytest

from multiform.cli import main
from multiform.errors import InvalidInput
from multiform.parallel import default_start_method, mp_context, ray_backend


def test_the_local_pool_forks_on_linux_and_refuses_an_unknown_start_method():
    if sys.platform.startswith("linux"):
        assert default_start_method() == "fork"
    assert mp_context("spawn").get_start_method() == "spawn"
    with pytest.raises(InvalidInput, match="start method 'threads'"):
        mp_context("threads")


def test_the_core_never_imports_ray():
    code = ("import sys, multiform.cli, multiform.job, multiform.adapt.evaluation, multiform.demos.record, "
            "multiform.parallel; print('ray' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_without_ray_installed_a_ray_option_is_a_clear_error(monkeypatch, tmp_path, capsys):
    monkeypatch.delitem(sys.modules, "multiform.cluster", raising=False)
    monkeypatch.setitem(sys.modules, "ray", None)          # what `import ray` finds when it is not installed
    with pytest.raises(InvalidInput, match=r"pip install 'multiform\[ray\]'"):
        ray_backend()
    out = tmp_path / "d.h5"
    assert main(["record", "pendulum", "--demos", "1", "--out", str(out), "--ray", "local"]) == 2
    assert "--ray: Ray is not installed" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("address, says", [("127.0.0.1:1", "cannot reach the Ray cluster at '127.0.0.1:1'"),
                                           ("nonsense", "'nonsense' is not auto, local, HOST:PORT")])
def test_a_ray_address_where_nothing_listens_is_refused_at_once(tmp_path, capsys, address, says):
    out = tmp_path / "d.h5"
    assert main(["record", "pendulum", "--demos", "1", "--out", str(out), "--ray", address]) == 2
    assert says in capsys.readouterr().err
    assert not out.exists()
