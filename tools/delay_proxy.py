#!/usr/bin/env python3
"""A TCP proxy that delays every byte by half a round trip each way.

Where `tc netem` is not available (no sch_netem module, no CAP_NET_ADMIN),
this stands in for a long link in front of a web server: each chunk read
from one side is written to the other RTT/2 later, in order, so a request
and its response take one RTT more, and throughput is not capped.

    tools/delay_proxy.py LISTEN_PORT UPSTREAM_HOST UPSTREAM_PORT RTT_MS [--seconds S]

Listens on 127.0.0.1 only (LISTEN_PORT 0: a free port); prints
"listening PORT" once it accepts. Runs until killed or for --seconds.
"""
import argparse
import asyncio
import time


async def pipe(reader, writer, delay):
    queue = asyncio.Queue()

    async def sender():
        while True:
            due, data = await queue.get()
            if data is None:
                break
            wait = due - time.monotonic()
            if wait > 0:
                await asyncio.sleep(wait)
            writer.write(data)
            await writer.drain()
        writer.close()

    task = asyncio.ensure_future(sender())
    try:
        while True:
            data = await reader.read(65536)
            if not data:
                break
            await queue.put((time.monotonic() + delay, data))
    except (ConnectionError, asyncio.CancelledError):
        pass
    await queue.put((0, None))
    await task


async def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("listen", type=int)
    ap.add_argument("host")
    ap.add_argument("port", type=int)
    ap.add_argument("rtt_ms", type=float)
    ap.add_argument("--seconds", type=float, default=0)
    a = ap.parse_args()
    half = a.rtt_ms / 2000.0

    async def handle(cr, cw):
        try:
            ur, uw = await asyncio.open_connection(a.host, a.port)
        except OSError:
            cw.close()
            return
        await asyncio.gather(pipe(cr, uw, half), pipe(ur, cw, half), return_exceptions=True)

    server = await asyncio.start_server(handle, "127.0.0.1", a.listen)
    print("listening", server.sockets[0].getsockname()[1], flush=True)
    async with server:
        if a.seconds > 0:
            await asyncio.sleep(a.seconds)
        else:
            await server.serve_forever()


if __name__ == "__main__":
    asyncio.run(main())
