"""Every command's --help prints and exits 0 (argparse formats help texts: a stray '%' breaks it)."""

from __future__ import annotations

from importlib.metadata import entry_points

import pytest

SCRIPTS = {ep.name: ep for ep in entry_points(group="console_scripts") if ep.value.startswith("mal_planner.")}


def test_the_commands_are_installed() -> None:
    assert {"mal-plan", "mal-launch", "mal-campaign", "mal-traffic", "mal-schedule", "mal-closed-loop"} <= set(SCRIPTS)


@pytest.mark.parametrize("name", sorted(SCRIPTS))
def test_help_exits_0(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        SCRIPTS[name].load()(["--help"])
    assert info.value.code == 0
    assert "usage:" in capsys.readouterr().out
