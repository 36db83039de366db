#!/usr/bin/env python3
"""What Foxglove's 3D panel (or RViz) shows of a bag, drawn with matplotlib 3D: no viewer runs on
this machine (no display, no Foxglove or RViz install), so the scene is rendered here from the
same recorded messages a viewer reads.

For each instant it takes the bag's ``/tf`` (tf2_msgs/TFMessage: inertial -> body, inertial ->
orbit) and ``markers/static`` and ``markers`` (visualization_msgs/MarkerArray) at that stamp, read with rosbags, and
draws every ARROW and CUBE marker the way a viewer does: its points in its ``frame_id``, moved by
its pose, then by the frame's transform into ``inertial`` (the fixed frame). The body box and
axes, the target attitude's axes (translucent), the wheel momentum vector (purple) and the
plumes of the thrusters firing in that step (the segments of the ``thrusters`` LINE_LIST)
appear; the orbit frame's axes are dashed.

    .venv/bin/python docs/figures/scene_3d.py                       # bags/eseo_backstepping_slew -> docs/figures/
    .venv/bin/python docs/figures/scene_3d.py BAG --times 0 10 40 --out FILE.png
"""
from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from rosbags.highlevel import AnyReader  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
BAG = ROOT / 'bags' / 'eseo_backstepping_slew' / 'bag'
OUT = ROOT / 'docs' / 'figures' / 'eseo_backstepping_slew_3d.png'
ARROW, CUBE, LINE_LIST, ADD = 0, 1, 5, 0


def read_scene(bag: Path, times_s) -> dict:
    """{stamp ns: {'tf': {child: Rotation}, 'markers': [...], 'error': deg}} at the wanted instants
    (each the latest message at or before it)."""
    wanted = sorted(round(t * 1e9) for t in times_s)
    out = {t: {'tf': {}, 'markers': [], 'static': [], 'error': None} for t in wanted}
    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections
                 if c.topic in ('/tf', '/markers', '/markers/static', '/error/eigenaxis')]
        for conn, stamp, raw in reader.messages(connections=conns):
            for t in wanted:
                if stamp > t:
                    continue
                msg = reader.deserialize(raw, conn.msgtype)
                if conn.topic == '/tf':
                    for tr in msg.transforms:
                        r = tr.transform.rotation
                        out[t]['tf'][tr.child_frame_id] = Rotation.from_quat([r.x, r.y, r.z, r.w])
                elif conn.topic == '/markers':
                    out[t]['markers'] = msg.markers
                elif conn.topic == '/markers/static':
                    out[t]['static'] = msg.markers
                else:
                    out[t]['error'] = msg.vector.x
    return out


def _in_inertial(marker, tf: dict, points: np.ndarray) -> np.ndarray:
    """Marker points (its frame, before its pose) -> inertial axes (frames share one origin)."""
    o, p = marker.pose.orientation, marker.pose.position
    local = Rotation.from_quat([o.x, o.y, o.z, o.w]).apply(points) + [p.x, p.y, p.z]
    frame = marker.header.frame_id
    return local if frame == 'inertial' else tf[frame].apply(local)


def _cube_edges(size: float) -> list[np.ndarray]:
    corners = np.array(list(itertools.product((-0.5, 0.5), repeat=3))) * size
    return [np.array([a, b]) for a, b in itertools.combinations(corners, 2)
            if np.isclose(np.linalg.norm(a - b), size)]


def draw(ax, scene: dict) -> None:
    for m in [*scene['static'], *scene['markers']]:
        if m.action != ADD:
            continue
        color = (m.color.r, m.color.g, m.color.b, max(m.color.a, 0.25))
        if m.type == ARROW:
            tail, head = _in_inertial(m, scene['tf'], np.array([[q.x, q.y, q.z] for q in m.points]))
            d = head - tail
            ax.quiver(*tail, *d, color=color, arrow_length_ratio=0.15, linewidth=2.5 if m.ns != 'target_axes' else 1.5)
        elif m.type == LINE_LIST and m.points:
            pts = _in_inertial(m, scene['tf'], np.array([[q.x, q.y, q.z] for q in m.points]))
            for a, b in pts.reshape(-1, 2, 3):
                ax.plot(*np.array([a, b]).T, color=color, linewidth=4)
        elif m.type == CUBE:
            for edge in _cube_edges(m.scale.x):
                e = _in_inertial(m, scene['tf'], edge)
                ax.plot(*e.T, color=(0.4, 0.4, 0.45), linewidth=0.8)
    if 'orbit' in scene['tf']:
        for axis, c in zip(np.eye(3), ('r', 'g', 'b')):
            ax.plot(*np.array([[0, 0, 0], 1.4 * scene['tf']['orbit'].apply(axis)]).T, c + '--', linewidth=0.7)
    ax.set_xlim(-1.2, 1.2), ax.set_ylim(-1.2, 1.2), ax.set_zlim(-1.2, 1.2)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel('x_i'), ax.set_ylabel('y_i'), ax.set_zlabel('z_i', labelpad=-2)
    ax.tick_params(labelsize=6)


def render(bag: Path, times_s, out: Path) -> Path:
    scenes = read_scene(bag, times_s)
    fig = plt.figure(figsize=(3.4 * len(scenes), 4.3))
    for i, (t, scene) in enumerate(scenes.items()):
        ax = fig.add_subplot(1, len(scenes), i + 1, projection='3d')
        ax.view_init(elev=22, azim=-60)
        draw(ax, scene)
        firing = sum(len(m.points) // 2 for m in scene['markers'] if m.ns == 'thrusters')
        ax.set_title(f't = {t * 1e-9:g} s\nerror {scene["error"]:.1f} deg, {firing} thrusters firing', fontsize=9)
    fig.suptitle(f'{bag.parent.name}, from its /tf, /markers/static and /markers (matplotlib; no viewer runs here): '
                 f'body box and axes x y z = red green blue (solid), target axes (translucent),\nwheel momentum '
                 f'(purple, 1 m = the wheel at its speed limit), plumes of the thrusters firing (orange), '
                 f'orbit frame (dashed), in the inertial frame', fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('bag', nargs='?', type=Path, default=BAG)
    ap.add_argument('--times', type=float, nargs='+', default=[0.0, 5.0, 15.0, 40.0, 299.9])
    ap.add_argument('--out', type=Path, default=OUT)
    args = ap.parse_args(argv)
    print(render(args.bag, args.times, args.out))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
