"""Loading a run for a report: a bag -> :class:`Run` (or a one-line :class:`BagError`), where its
report goes, and the series the report derives from it (controller status values, the commanded
torque, fault events, missing topics). No matplotlib here."""
from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mcap.exceptions import McapError

from adcs_msgs_py import names as topics
from adcs_sim.app.analysis.metrics import RunData, run_metrics
from adcs_sim.app.report import envelope
from adcs_sim.app.analysis.run_data import TooLong
from adcs_sim.app.analysis.status_records import TORQUE_KEYS, status_keys, status_names, status_values

ERROR_LEVEL = 2  # diagnostic_msgs/DiagnosticStatus.ERROR

# Exceptions that mean "this input is not a readable bag" (reported in one line, no traceback).
BAG_ERRORS: tuple[type[BaseException], ...] = (OSError, ValueError, EOFError, struct.error, McapError)
try:
    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag2 import ReaderError
    from rosbags.serde import SerdeError
    BAG_ERRORS += (AnyReaderError, ReaderError, SerdeError)
except ImportError:  # pragma: no cover - other rosbags versions
    pass


def bag_folder(path) -> Path | None:
    """The bag folder of ``path`` (the folder itself, or the folder of a ``<folder>_0.mcap`` file)."""
    path = Path(os.path.abspath(path))
    if path.is_dir():
        return path
    parent = path.parent
    if (parent / 'metadata.yaml').exists() or path.stem.startswith(parent.name + '_'):
        return parent
    return None


def run_name(path) -> str:
    """A run's name: the run folder holding ``bag/`` (``runs/<name>/bag``), else the bag's name."""
    folder = bag_folder(path)
    if folder is None:
        return Path(path).stem
    return folder.parent.name if folder.name == 'bag' and folder.parent.name else folder.name


def default_report_dir(path) -> Path:
    """``<bag>/../report``: a ``report`` folder beside the bag folder."""
    folder = bag_folder(path)
    if folder is None:
        p = Path(os.path.abspath(path))
        return p.parent / f'{p.stem}-report'
    return folder.parent / 'report'


@dataclass
class Run:
    """A loaded run: the bag, its name and its time series.

    A long run (more state samples than :data:`~.envelope.MAX_POINTS`) is streamed
    (:mod:`.long_run`): ``data`` then holds the samples its report draws, and ``long`` the
    whole-run numbers (its metrics at the tolerances it was loaded with, its sample count)."""

    path: Path
    name: str
    data: RunData
    long: object = None     # long_run.LongSummary, or None: ``data`` holds the whole run

    @property
    def samples(self) -> int:
        """State samples of the whole run."""
        return int(self.data.t.size) if self.long is None else self.long.samples

    def metrics(self, tol_deg: float = 0.5, eigen_tol_deg: float | None = None) -> dict:
        """:func:`~adcs_sim.app.analysis.metrics.run_metrics` of the whole run."""
        eigen_tol_deg = tol_deg if eigen_tol_deg is None else eigen_tol_deg
        if self.long is None:
            return run_metrics(self.data, tol_deg, eigen_tol_deg)
        if self.long.tol != (tol_deg, eigen_tol_deg):   # streamed again at these tolerances
            # lazy: long_run: only a long run needs it (see _load_long)
            from adcs_sim.app.report.long_run import load_long, release_memory   # see _load_long
            self.data, self.long = load_long(self.path, tol_deg, eigen_tol_deg)
            release_memory()
        return self.long.metrics

    @property
    def complete(self) -> bool:
        """False when the bag was recovered from a truncated file (writer killed, no summary)."""
        return not self.data.truncated

    @property
    def message_count(self) -> int:
        """Messages read from the bag (all topics)."""
        return int(self.data.message_count)


class BagError(Exception):
    """An input that is not a readable bag of the graph (the message is one line)."""


def load_run(path, name: str | None = None, tol_deg: float = 0.5, eigen_tol_deg: float | None = None,
             stream: bool = True) -> Run:
    """Check and read a bag; raises :class:`BagError` (one-line message) if it cannot be used.

    ``stream``: a long run is streamed (:class:`Run`; its metrics at ``tol_deg``,
    ``eigen_tol_deg``), unless the report needs what that does not cover (then it is read whole);
    False: always read whole (a comparison overlays whole series)."""
    long = None
    try:
        try:
            data = RunData.from_bag(path, max_samples=envelope.MAX_POINTS if stream else None)
        except TooLong:
            data = None    # (streamed below: out of this block, the partial reading's frames let go)
        if data is None:
            data, long = _load_long(path, tol_deg, eigen_tol_deg)
    except BAG_ERRORS as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        reason = reason[len(str(path)) + 2:] if reason.startswith(f'{path}: ') else reason
        raise BagError(reason) from None
    return Run(Path(path), name or run_name(path), data, long)


def _load_long(path, tol_deg: float, eigen_tol_deg: float | None):
    """(data, summary) of a long run streamed, or (the whole run, None) where streaming does not
    cover it (long_run.Unstreamable)."""
    # lazy: long_run and the streamed metrics it brings are ~0.08 s of every adcs-analyze start
    # (python -X importtime), and only a long run needs them
    from adcs_sim.app.report.long_run import Unstreamable, load_long, release_memory
    try:
        return load_long(path, tol_deg, eigen_tol_deg)
    except Unstreamable:
        return RunData.from_bag(path), None
    finally:
        release_memory()


# --- derived series ---------------------------------------------------------------------------

def status_series(run: RunData) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Controller status values per key: ``{key: (t, values)}``, values float where all parse, else str.

    Keys are prefixed ``<status name>/`` when several controllers publish. Read key by key from the
    records' columns (:func:`~adcs_sim.app.analysis.status_records.status_column`), not record by record.
    """
    records = run.controller_status
    several = len(status_names(records)) > 1
    out = {}
    for name, key in status_keys(records):
        out[f'{name}/{key}' if several else key] = status_values(records, key, name)
    return out


def commanded_torque(run: RunData) -> tuple[np.ndarray, np.ndarray] | None:
    """(t, u (N, 3)) from the controller's status values ``u_x, u_y, u_z``, or None."""
    series = status_series(run)
    for prefix in [''] + sorted({k.rsplit('/', 1)[0] + '/' for k in series if '/' in k}):
        keys = [prefix + k for k in TORQUE_KEYS]
        if all(k in series and series[k][1].dtype != object for k in keys):
            t = series[keys[0]][0]
            if all(series[k][0].shape == t.shape for k in keys):
                return t, np.column_stack([series[k][1] for k in keys])
    return None


def fault_events(run: RunData) -> list[tuple[float, str, str]]:
    """(t, name, message) of every fault onset: an ERROR status whose previous same-name status was not."""
    last: dict[str, int] = {}
    events = []
    for t, level, name, message in sorted(run.faults, key=lambda r: r[0]):
        if level == ERROR_LEVEL and last.get(name) != ERROR_LEVEL:
            events.append((float(t), name, message))
        last[name] = level
    return events


def has_wheels(scenario: dict | None) -> bool:
    """Whether the scenario's spacecraft has reaction wheels (True when there is no scenario)."""
    if scenario is None:
        return True
    dyn = (scenario.get('dynamics') or {}).get('ros__parameters') or {}
    return bool(isinstance(dyn, dict) and (dyn.get('wheels') or {}).get('names'))


def missing_topics(run: RunData) -> list[str]:
    """Topics of the graph with no message in the bag (``RunData.missing_topics``); ``wheels/state``
    only when the spacecraft has wheels."""
    wheels = has_wheels(run.scenario)
    return [t for t in run.missing_topics if wheels or t != topics.WHEELS_STATE]


def thruster_topics(run: RunData) -> list[str]:
    return sorted(t for t in run.topic_counts if 'thruster' in t)
