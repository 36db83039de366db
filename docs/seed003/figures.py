#!/usr/bin/env python3
"""Seed 003 section 5.2 (Fig. 4-7): controllers A and B from the same initial condition, read from
the graph's recordings bags/pointing_controller_{a,b}. Writes docs/seed003/comparison.png.

    .venv/bin/python docs/seed003/figures.py
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from adcs_sim.app.analysis.metrics import RunData, pointing_error_deg  # noqa: E402


def main() -> None:
    from matplotlib.figure import Figure
    runs = {k: RunData.from_bag(ROOT / 'bags' / f'pointing_controller_{k}' / 'bag') for k in 'ab'}
    fig = Figure(figsize=(7.0, 8.0), layout='constrained')
    axes = fig.subplots(4, 1, sharex=True)
    for k, color in (('a', 'tab:blue'), ('b', 'tab:red')):
        r = runs[k]
        st = r.controller_status
        ts = np.array([t for t, _, _ in st])
        mode = [v['mode'] for _, _, v in st]
        e_phi = np.degrees([float(v['e_phi']) for _, _, v in st])
        e_psi = np.degrees([float(v['e_psi']) for _, _, v in st])
        label = 'A' if k == 'a' else 'B'
        if k == 'a':
            switch = ts[mode.index('A2_lqr')]
            for ax in axes:
                ax.axvline(switch, color='tab:blue', linestyle=':', linewidth=1)
        axes[0].semilogy(r.t, np.maximum(pointing_error_deg(r), 1e-7), color=color, label=label)
        axes[1].plot(r.t, np.degrees(np.linalg.norm(r.w, axis=1)), color=color)
        axes[2].plot(ts, e_phi, color=color)
        axes[3].plot(ts, e_psi, color=color)
    axes[0].set_ylabel('pointing error (deg)')
    axes[0].legend(title='controller (dotted: A switches to the LQR)', fontsize='small')
    axes[1].set_ylabel('|ω| (deg/s)')
    axes[2].set_ylabel('e_Φ (deg)')
    axes[3].set_ylabel('e_Ψ (deg)')
    axes[3].set_xlabel('time (s)')
    for ax in axes:
        ax.grid(True, which='both', alpha=0.3)
    out = ROOT / 'docs' / 'seed003' / 'comparison.png'
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == '__main__':
    main()
