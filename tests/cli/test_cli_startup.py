"""`skytrack --help` starts fast: the CLI modules import neither numpy nor the heavy libraries."""

from __future__ import annotations

import json
import subprocess
import sys

HEAVY = ("numpy", "pandas", "scipy", "matplotlib", "pyarrow")


def _modules_after(code: str) -> set[str]:
    probe = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return set(json.loads(done.stdout.strip().splitlines()[-1]))


def _heavy(modules: set[str]) -> list[str]:
    return sorted(name for name in modules if name.split(".")[0] in HEAVY)


def test_importing_the_cli_imports_no_heavy_library():
    loaded = _modules_after("import skytrack.cli.main")
    assert _heavy(loaded) == []
    assert "skytrack.tracker" not in loaded and "skytrack.app.run" not in loaded


def test_help_imports_no_heavy_library():
    code = (
        "import sys\nfrom skytrack.cli.main import app\n"
        "for args in (['--help'], ['track', '--help'], ['study', 'singer-missed', '--help']):\n"
        "    try:\n        app(args, standalone_mode=False)\n    except SystemExit:\n        pass\n"
    )
    assert _heavy(_modules_after(code)) == []


def test_the_package_itself_is_light():
    assert _heavy(_modules_after("import skytrack")) == []
