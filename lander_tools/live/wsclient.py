"""A small synchronous client of the Foxglove WebSocket protocol (subprotocol ``foxglove.sdk.v1``),
for the live tests and ``bench/live.py``: ``websockets`` in a thread of its own, everything the
server sends is kept. (The student page has its own client in JavaScript: ``web/foxglove.js``.)
"""
from __future__ import annotations

import asyncio
import json
import struct
import threading
import time
from collections import defaultdict
from collections.abc import Callable
from typing import Any

SUBPROTOCOL = "foxglove.sdk.v1"


def wait_until(pred: Callable[[], Any], timeout: float, what: str, poll: float = 0.02) -> Any:
    """Poll ``pred`` until it returns something truthy (returned); TimeoutError naming ``what``."""
    deadline = time.monotonic() + timeout
    while True:
        value = pred()
        if value:
            return value
        if time.monotonic() > deadline:
            raise TimeoutError(f"{what} not reached within {timeout} s")
        time.sleep(poll)


class FoxgloveClient:
    """A Foxglove protocol client with a blocking API. Everything received is kept:
    ``messages[topic]`` is a list of ``(wall_time, log_time_ns, payload_bytes)``."""

    def __init__(self, port: int, timeout: float = 30.0) -> None:
        self.port = port
        self.channels: dict[str, dict[str, Any]] = {}
        self.services: dict[str, dict[str, Any]] = {}
        self.messages: dict[str, list[tuple[float, int, bytes]]] = defaultdict(list)
        self.texts: list[dict[str, Any]] = []
        self.server_info: dict[str, Any] | None = None
        self.subprotocol: str | None = None
        self._sub_topic: dict[int, str] = {}
        self._responses: dict[int, dict[str, Any]] = {}
        self._next = 1
        self._client_channels: dict[str, int] = {}
        self._loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout) or self._error is not None:
            raise RuntimeError(f"cannot connect to ws://127.0.0.1:{port}: {self._error}")

    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)
        self._loop.run_until_complete(self._main())

    async def _main(self) -> None:
        import websockets
        from websockets.typing import Subprotocol

        try:
            self.ws = await websockets.connect(f"ws://127.0.0.1:{self.port}", subprotocols=[Subprotocol(SUBPROTOCOL)],
                                               max_size=None)
        except Exception as exc:  # noqa: BLE001 - reported by the constructor
            self._error = exc
            self._ready.set()
            return
        self.subprotocol = self.ws.subprotocol
        self._ready.set()
        try:
            async for m in self.ws:
                if isinstance(m, str):
                    self._on_text(json.loads(m))
                else:
                    self._on_binary(m)
        except Exception:  # noqa: BLE001 - connection closed at the end of a test
            pass

    def _on_text(self, d: dict[str, Any]) -> None:
        self.texts.append(d)
        if d["op"] == "serverInfo":
            self.server_info = d
        elif d["op"] == "advertise":
            for c in d["channels"]:
                self.channels[c["topic"]] = c
        elif d["op"] == "advertiseServices":
            for s in d["services"]:
                self.services[s["name"]] = s
        elif d["op"] == "serviceCallFailure":
            self._responses[d["callId"]] = {"failure": d["message"]}

    def _on_binary(self, m: bytes) -> None:
        op = m[0]
        if op == 1:
            sid, t_ns = struct.unpack_from("<IQ", m, 1)
            self.messages[self._sub_topic[sid]].append((time.monotonic(), t_ns, bytes(m[13:])))
        elif op == 3:
            _sid, call_id, enc_len = struct.unpack_from("<III", m, 1)
            self._responses[call_id] = json.loads(m[13 + enc_len:])

    def _send(self, data: str | bytes) -> None:
        asyncio.run_coroutine_threadsafe(self.ws.send(data), self._loop).result(10.0)

    def close(self) -> None:
        if not self._thread.is_alive():  # the server closed the connection: nothing left to close
            return
        try:
            asyncio.run_coroutine_threadsafe(self.ws.close(), self._loop).result(5.0)
        except Exception:  # noqa: BLE001
            pass
        self._thread.join(5.0)

    # --- API --------------------------------------------------------------------------------

    def wait_channels(self, topics: list[str], timeout: float = 30.0) -> None:
        wait_until(lambda: all(t in self.channels for t in topics), timeout, f"advertised channels {topics}")

    def subscribe(self, topics: list[str]) -> None:
        subs = []
        for t in topics:
            sid, self._next = self._next, self._next + 1
            self._sub_topic[sid] = t
            subs.append({"id": sid, "channelId": self.channels[t]["id"]})
        self._send(json.dumps({"op": "subscribe", "subscriptions": subs}))

    def json_messages(self, topic: str) -> list[dict[str, Any]]:
        return [json.loads(p) for _, _, p in list(self.messages[topic])]

    def latest(self, topic: str) -> dict[str, Any] | None:
        msgs = self.messages[topic]
        if not msgs:
            return None
        record: dict[str, Any] = json.loads(msgs[-1][2])
        return record

    def call(self, service: str, request: Any, timeout: float = 30.0) -> dict[str, Any]:
        call_id, self._next = self._next, self._next + 1
        payload = request if isinstance(request, bytes) else json.dumps(request).encode()
        self._send(bytes([2]) + struct.pack("<III", self.services[service]["id"], call_id, 4) + b"json" + payload)
        answer: dict[str, Any] = wait_until(lambda: self._responses.get(call_id), timeout, f"answer of {service}")
        return answer

    def set_parameters(self, params: list[dict[str, Any]], timeout: float = 30.0) -> list[dict[str, Any]]:
        rid = f"set-{self._next}"
        self._next += 1
        self._send(json.dumps({"op": "setParameters", "parameters": params, "id": rid}))
        reply = wait_until(lambda: next((t for t in self.texts if t.get("op") == "parameterValues"
                                         and t.get("id") == rid), None), timeout, "parameterValues")
        values: list[dict[str, Any]] = reply["parameters"]
        return values

    def publish(self, topic: str, payload: bytes) -> None:
        if topic not in self._client_channels:
            cid, self._next = self._next, self._next + 1
            self._client_channels[topic] = cid
            self._send(json.dumps({"op": "advertise", "channels": [
                {"id": cid, "topic": topic, "encoding": "json", "schemaName": topic}]}))
        self._send(bytes([1]) + struct.pack("<I", self._client_channels[topic]) + payload)

    def statuses(self) -> list[str]:
        return [t["message"] for t in self.texts if t.get("op") == "status"]
