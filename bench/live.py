"""Benchmark: what ``lander live`` costs a flight, and how fast the page is fed.

Each case is a real ``lander fly`` (subprocess) of ``hover-canted`` at speed 0 (as fast as
possible) in lockstep with dt = 0.02 s (``--dt``; 50 states per sim second, 5x the scene's, so
the bridge has 5x the messages to take), recording ``/lander/state``; the runs alternate in one session so the
machine's load hits both alike:

* ``without``: the flight alone;
* ``with live + 1 client``: ``lander fly --live`` (the bridge starts with the nodes and is
  matched before the reset) and one Foxglove client
  (:class:`lander_tools.live.wsclient.FoxgloveClient`) subscribed to every channel from the
  moment the bridge serves.

Figures: the real-time factor (the flight's summary line; and over the flying part only: sim time
span of the recorded states over their receive-time span), the ratio with/without (median over
the repeats; goal: at most 10 % slower), and whether the
recorded states are **bit-identical** (the CDR bytes of every state from the reset on). Then one
flight at speed 1 with dt = 0.02 s (50 states per sim second) and a client: the ``/live/state``
rate the page gets [Hz, wall] (goal: >= 30).

    python bench/live.py [--quick] [--repeats N] [--duration S] [--json F]
"""
from __future__ import annotations

import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:  # `python bench/live.py` from a source checkout
    sys.path.insert(0, str(REPO))

from bench._common import parser, table, write_json  # noqa: E402 - after the sys.path line above

CHANNELS = ["/live/state", "/live/scene", "/live/tf", "/live/events", "/live/status"]
_RTF = re.compile(r"(?:RTF|real-time factor) ([0-9.]+)x")


def _free_port() -> int:
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _connect(port: int, proc: subprocess.Popen, channels: list[str]) -> object | None:
    """A client subscribed to ``channels`` as soon as the flight's bridge serves (None if the
    flight ended first)."""
    from lander_tools.live.wsclient import FoxgloveClient

    while proc.poll() is None:
        try:
            client = FoxgloveClient(port, timeout=2.0)
        except RuntimeError:
            time.sleep(0.05)
            continue
        client.wait_channels(channels)
        client.subscribe(channels)
        return client
    return None


def fly(tmp: Path, name: str, duration: float, live: bool, dt: float) -> dict[str, object]:
    """One flight (``lander fly ... [--live]``); returns its RTF, the states' CDR bytes from the
    reset on, and how many states the client got."""
    bag = tmp / name
    port = _free_port()
    params = tmp / f"{name}.params.yaml"
    params.write_text(f"lander_sim:\n  ros__parameters:\n    dt: {dt}\n")
    cmd = [sys.executable, "-m", "lander_tools.cli", "fly", "hover-canted", "--speed", "0", "--duration",
           str(duration), "--no-progress", "--record", str(bag), "--topics", "/lander/state", "--params", str(params)]
    if live:
        cmd += ["--live", "--port", str(port)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    client = _connect(port, proc, CHANNELS) if live else None
    stdout, stderr = proc.communicate()
    received = 0
    if client is not None:
        received = len(client.messages["/live/state"])
        client.close()
    m = _RTF.search(stdout)
    if proc.returncode != 0 or m is None:
        raise RuntimeError(f"flight {name} failed (exit {proc.returncode}):\n{stdout[-2000:]}\n{stderr[-2000:]}")
    states, rtf_flying = _states(bag)
    return {"rtf": float(m.group(1)), "rtf_flying": rtf_flying, "states": states, "received": received}


def _states(bag: Path) -> tuple[list[bytes], float]:
    """The CDR bytes of every /lander/state from the last state 1 (the launcher's reset) on, and
    the flying part's real-time factor: sim time span over the recorder's receive-time span."""
    from rosbags.rosbag2 import Reader

    with Reader(bag) as reader:
        msgs = [(t_ns, data) for _, t_ns, data in reader.messages(connections=reader.connections)]

    # CDR: 4 bytes encapsulation, header.stamp (int32 sec, uint32 nanosec), frame_id (uint32
    # length + bytes), then the uint64 sequence aligned to 8 bytes of the payload.
    def sequence(data: bytes) -> int:
        n = int.from_bytes(data[12:16], "little")
        off = 16 + n
        off += (-(off - 4)) % 8
        return int.from_bytes(data[off:off + 8], "little")

    def sim_time(data: bytes) -> float:
        return int.from_bytes(data[4:8], "little", signed=True) + int.from_bytes(data[8:12], "little") * 1e-9

    starts = [i for i, (_, d) in enumerate(msgs) if sequence(d) == 1]
    msgs = msgs[starts[-1]:] if starts else msgs
    wall = (msgs[-1][0] - msgs[0][0]) * 1e-9
    rtf = (sim_time(msgs[-1][1]) - sim_time(msgs[0][1])) / wall if wall > 0 else float("nan")
    return [d for _, d in msgs], rtf


def page_rate(seconds: float) -> float:
    """States per wall second a client gets at speed 1 with 50 states per sim second."""
    from lander_tools.live.wsclient import wait_until

    with tempfile.TemporaryDirectory() as tmp:
        params = Path(tmp) / "params.yaml"
        params.write_text("lander_sim:\n  ros__parameters:\n    dt: 0.02\n")
        port = _free_port()
        flight = subprocess.Popen([sys.executable, "-m", "lander_tools.cli", "fly", "hover-canted", "--speed", "1",
                                   "--duration", str(seconds + 30), "--no-progress", "--params", str(params),
                                   "--live", "--port", str(port)],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            client = _connect(port, flight, ["/live/state"])
            if client is None:
                raise RuntimeError("the speed-1 flight ended before its bridge served")
            wait_until(lambda: len(client.messages["/live/state"]) > 10, 90.0, "the flight under way")
            n0, w0 = len(client.messages["/live/state"]), time.monotonic()
            time.sleep(seconds)  # the measuring window
            rate = (len(client.messages["/live/state"]) - n0) / (time.monotonic() - w0)
            client.close()
        finally:
            flight.terminate()
            flight.wait(30)
    return rate


def main() -> int:
    p = parser(__doc__.split("\n\n")[0])
    p.add_argument("--repeats", type=int, default=None, help="flights per case (default 3, --quick 1)")
    p.add_argument("--duration", type=float, default=None, help="sim seconds per flight (default 120, --quick 30)")
    p.add_argument("--dt", type=float, default=0.02,
                   help="physics step = control period [s] (default 0.02: 50 states per sim second)")
    args = p.parse_args()
    repeats = args.repeats or (1 if args.quick else 3)
    duration = args.duration or (30.0 if args.quick else 120.0)
    os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 100))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    rows, data = [], {"duration": duration, "runs": []}
    with tempfile.TemporaryDirectory() as tmp:
        base = None
        for k in range(repeats):
            for live in (False, True):
                r = fly(Path(tmp), f"{'live' if live else 'plain'}-{k}", duration, live, args.dt)
                base = base if base is not None else r["states"]
                identical = r["states"] == base
                data["runs"].append({"live": live, "rtf": r["rtf"], "rtf_flying": r["rtf_flying"],
                                     "states": len(r["states"]),
                                     "identical_to_first": identical, "client_states": r["received"]})
                rows.append(["with live + 1 client" if live else "without", k + 1, r["rtf"], r["rtf_flying"],
                             len(r["states"]),
                             "yes" if identical else "NO", r["received"] if live else "-"])
    print(table(f"hover-canted, dt {args.dt:g} s, speed 0, lockstep, {duration:g} s of sim time per flight",
                ["case", "run", "RTF (summary)", "RTF (flying, bag)", "states", "bit-identical", "client got"], rows))
    for key, what in (("rtf", "the flight's summary"), ("rtf_flying", "the flying part, from the bag")):
        plain = [r[key] for r in data["runs"] if not r["live"]]
        live_ = [r[key] for r in data["runs"] if r["live"]]
        ratio = statistics.median(live_) / statistics.median(plain)
        data[f"{key}_ratio"] = ratio
        print(f"median RTF ({what}) with / without: {statistics.median(live_):.3g} / {statistics.median(plain):.3g} "
              f"= {ratio:.3f} ({(1 - ratio) * 100:+.1f} % slower; goal <= 10 %)")
    rate = page_rate(5.0 if args.quick else 10.0)
    data["page_rate_hz"] = rate
    print(f"/live/state to a client at speed 1, 50 states per sim second: {rate:.1f} Hz (goal >= 30)")
    write_json(args.json, data)
    return 0 if all(r["identical_to_first"] for r in data["runs"]) else 1


if __name__ == "__main__":
    sys.exit(main())
