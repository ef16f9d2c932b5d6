"""Upload the trajectories of ``python -m swarmplan.export RUN.mcap --format crazyflie --out DIR``
to Crazyflies and fly them together.

    python examples/crazyflie_upload.py DIR --uri cf1=radio://0/80/2M/E7E7E7E701 \\
        --uri cf2=radio://0/80/2M/E7E7E7E702 [--takeoff-time 3] [--dry-run]

Each Crazyflie gets its agent's trajectory (``manifest.json`` names the file) in its trajectory
memory, defined as trajectory 1 of the high-level commander; all take off, go to their
trajectory's start, and start their trajectories together (each after its ``start_time``),
then land. The flight room's positioning system must share the world's frame (``docs/export.md``).
Needs cflib: ``pip install -e '.[crazyflie]'``. ``--dry-run`` checks the files and the memory
and connects to nothing.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import threading
import time
from pathlib import Path

PIECE_BYTES = 132  # cflib Poly4D.pack: 33 float32
MEMORY_BYTES = 4096  # the Crazyflie's trajectory memory
TRAJECTORY_ID = 1


def read_pieces(path: Path) -> list[list[float]]:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return [[float(v) for v in row] for row in rows[1:] if row]


def upload(cf, pieces: list[list[float]]) -> float:  # noqa: ANN001 - a cflib Crazyflie
    """Write the pieces to the trajectory memory and define trajectory 1; returns its duration."""
    from cflib.crazyflie.mem import MemoryElement, Poly, Poly4D

    mem = cf.mem.get_mems(MemoryElement.TYPE_TRAJ)[0]
    mem.trajectory = [
        Poly4D(row[0], Poly(row[1:9]), Poly(row[9:17]), Poly(row[17:25]), Poly(row[25:33])) for row in pieces
    ]
    if not mem.write_data_sync():
        raise RuntimeError("trajectory upload failed")
    cf.high_level_commander.define_trajectory(TRAJECTORY_ID, 0, len(mem.trajectory))
    return sum(row[0] for row in pieces)


def fly(
    uri: str, pieces: list[list[float]], start_time: float, go: threading.Barrier, takeoff: float
) -> None:
    from cflib.crazyflie import Crazyflie
    from cflib.crazyflie.syncCrazyflie import SyncCrazyflie

    with SyncCrazyflie(uri, cf=Crazyflie(rw_cache="./cache")) as scf:
        cf = scf.cf
        duration = upload(cf, pieces)
        hlc = cf.high_level_commander
        x0, y0, z0 = pieces[0][1], pieces[0][9], pieces[0][17]
        hlc.takeoff(z0, takeoff)
        time.sleep(takeoff)
        hlc.go_to(x0, y0, z0, 0.0, takeoff)
        time.sleep(takeoff)
        go.wait()  # every Crazyflie at its start: the common start
        time.sleep(start_time)
        hlc.start_trajectory(TRAJECTORY_ID, 1.0, False)
        time.sleep(duration)
        hlc.land(0.0, takeoff)
        time.sleep(takeoff)
        hlc.stop()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", help="the export's folder (with manifest.json)")
    ap.add_argument("--uri", action="append", default=[], metavar="ID=URI", help="a Crazyflie for an agent")
    ap.add_argument(
        "--takeoff-time", type=float, default=3.0, help="s for takeoff, going to the start, landing"
    )
    ap.add_argument("--dry-run", action="store_true", help="check the files only")
    args = ap.parse_args(argv)
    folder = Path(args.folder)
    manifest = json.loads((folder / "manifest.json").read_text())
    if manifest.get("format") != "crazyflie":
        print(f"{folder}: not a Crazyflie export (format {manifest.get('format')!r})", file=sys.stderr)
        return 2
    uris = dict(u.split("=", 1) for u in args.uri)
    jobs = []
    for entry in manifest["agents"]:
        pieces = read_pieces(folder / entry["file"])
        size = len(pieces) * PIECE_BYTES
        if size > MEMORY_BYTES:
            print(f"{entry['id']}: {size} bytes do not fit the {MEMORY_BYTES}-byte memory", file=sys.stderr)
            return 2
        print(f"{entry['id']}: {len(pieces)} pieces, {size} bytes, start at +{entry['start_time']:g} s")
        if entry["id"] in uris:
            jobs.append((uris[entry["id"]], pieces, float(entry["start_time"])))
    if args.dry_run or not jobs:
        return 0
    try:
        import cflib.crtp
    except ImportError:
        print("needs cflib: pip install -e '.[crazyflie]' (or pip install cflib)", file=sys.stderr)
        return 2
    cflib.crtp.init_drivers()
    go = threading.Barrier(len(jobs))
    threads = [threading.Thread(target=fly, args=(*job, go, args.takeoff_time)) for job in jobs]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    return 0


if __name__ == "__main__":
    sys.exit(main())
