"""Basilisk (``bsk``) for the benchmarks, in a throwaway venv: never in the project's own.

:func:`basilisk_python` creates ``/tmp/adcs_bsk_venv`` (or ``$ADCS_BSK_VENV``) and installs
``bsk==2.12.1`` into it with pip on first use; it returns that interpreter, or None with the
reason when it cannot (no network, no wheel for this platform, ...). :func:`run_child` runs one of
the ``bsk_*.py`` child scripts beside this file with it and returns its JSON answer.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

BSK = 'bsk==2.12.1'
HERE = Path(__file__).resolve().parent


def basilisk_python() -> tuple[Path | None, str]:
    """(python of a venv that imports Basilisk, '') or (None, why not)."""
    venv = Path(os.environ.get('ADCS_BSK_VENV', '/tmp/adcs_bsk_venv'))
    python = venv / 'bin' / 'python'
    probe = [str(python), '-c', 'import Basilisk']
    if python.exists() and subprocess.run(probe, capture_output=True).returncode == 0:
        return python, ''
    print(f'installing {BSK} into the throwaway venv {venv} (not the project venv) ...', flush=True)
    steps = [[sys.executable, '-m', 'venv', str(venv)],
             [str(python), '-m', 'pip', 'install', '--quiet', '--disable-pip-version-check', BSK]]
    for cmd in steps:
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode != 0:
            tail = (done.stderr or done.stdout).strip().splitlines()[-3:]
            return None, f'{" ".join(cmd[-2:])} failed: {" | ".join(tail)}'
    if subprocess.run(probe, capture_output=True).returncode != 0:
        return None, f'{BSK} installed but "import Basilisk" fails'
    return python, ''


def run_child(python: Path, script: str, args: dict) -> tuple[dict | None, str]:
    """Run ``HERE/script`` with Basilisk's python; its last stdout line is a JSON object."""
    done = subprocess.run([str(python), str(HERE / script), json.dumps(args)], capture_output=True, text=True)
    lines = done.stdout.strip().splitlines()
    if done.returncode != 0 or not lines:
        tail = done.stderr.strip().splitlines()[-3:]
        return None, f'{script} failed (exit {done.returncode}): {" | ".join(tail)}'
    return json.loads(lines[-1]), ''
