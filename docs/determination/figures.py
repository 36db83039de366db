"""The figures of docs/determination.md, regenerated: ``.venv/bin/python docs/determination/figures.py``.

They use the estimators' own test truth models (tests/support/estimation_truth.py: the Farrenkopf gyro with
exact discrete variances, white star tracker noise; StateSensors on the plant's true state) until the
truth model's sensor suite is merged; the figures are drawn by adcs_sim/app/report/estimation.py.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1] / 'tests'))   # the test truth models (see the docstring)

from support.estimator_runs import batch, write_run_bag  # noqa: E402

from adcs_sim.app.analysis import estimation  # noqa: E402
from adcs_sim.app.report import estimation as figures  # noqa: E402


def _png(fig, name: str) -> None:
    fig.savefig(HERE / f'{name}.png', dpi=110)


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        write_run_bag(tmp / 'bag')
        s = estimation.series_from_bag(tmp / 'bag')
        _png(figures.estimation_figure(s, settle_s=20.0, title='MEKF (gyro + star tracker), read from a bag'),
             'mekf_from_bag')
        result = batch(tmp, 20, seeds=list(range(20))).run()
        s = estimation.series_from_batch(result, 0)
        _png(figures.estimation_figure(s, settle_s=50.0, title='PD slew flown on the MEKF estimate '
                                       '(batch, run 0 of 20)'), 'pd_slew_on_mekf')
        c = estimation.batch_consistency(result)
        _png(figures.consistency_figure(c, result.t, 20, 'PD slew on the MEKF estimate: mean NEES of 20 runs'),
             'pd_slew_on_mekf_nees')
        print({k: v for k, v in c.items() if k != 'nees'})


if __name__ == '__main__':
    main()
