"""Feed a text into a live vtts session a few words at a time, as a language model writes it.

    .venv/bin/vtts serve --model cybatt &          # then open http://127.0.0.1:8080/
    .venv/bin/python samples/serve_llm.py          # this text spoken by a session of its own

or, with no server running, ``--serve`` starts one in this process. Each clause is spoken as soon
as it is complete (``append``); ``flush`` ends the utterance. What the session streams back is
printed: each clause as it arrives, with the time since the first words were sent, its audio
and face, and its words on the audio's clock.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import time

from vtts.serve import Client, protocol

TEXT = (
    "Sure! <smile> Here is how it works: I receive your text a few words at a time, "
    "and I start speaking as soon as the first clause is complete. <nod> Each clause "
    "comes back as sound and as MPEG-4 face parameters, on the same clock. Bye for now!"
)


async def feed(url: str, text: str, words: int, interval: float) -> None:
    async with Client(url) as session:
        opened = await session.open()
        print(f"session {opened['session']}: {opened['model']}, {len(opened['params'])} "
              f"parameters a frame at {opened['fps']:g} Hz")  # fmt: skip
        start = time.monotonic()

        async def writer() -> None:
            pieces = text.split(" ")
            for k in range(0, len(pieces), words):
                await session.append(" ".join(pieces[k : k + words]) + " ")
                await asyncio.sleep(interval)  # a language model's pace: tokens come and go
            await session.flush()

        task = asyncio.create_task(writer())
        audio = face = 0
        while True:
            m = await session.receive()
            now = time.monotonic() - start
            if isinstance(m, protocol.AudioChunk):
                audio += m.samples.nbytes
            elif isinstance(m, protocol.FaceFrames):
                face += m.values.nbytes
            elif m["type"] == "clause":
                said = " ".join(w[2] for w in m["words"])
                seconds = m["samples"] / m["rate"]
                print(f"{now:6.2f} s  clause {m['clause']} at {m['start']:.2f} s of the audio, "
                      f"{seconds:.2f} s, {m['frames']} frames: {said}")  # fmt: skip
            elif m["type"] == "error":
                print(f"{now:6.2f} s  error: {m['message']}")
            elif m["type"] == "end":
                print(f"{now:6.2f} s  end: {m['duration']:.2f} s of speech; {audio:,} bytes of "
                      f"audio, {face:,} of face")  # fmt: skip
                break
        await task


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--url", default="http://127.0.0.1:8080", help="the vtts serve to talk to")
    p.add_argument("--serve", action="store_true", help="start a server (cybatt) in this process")
    p.add_argument("--text", default=TEXT, help="the text (bookmarks allowed)")
    p.add_argument("--words", type=int, default=3, help="words per piece (default 3)")
    p.add_argument("--interval", type=float, default=0.1, help="seconds between pieces")
    args = p.parse_args()
    with contextlib.ExitStack() as stack:
        url = args.url
        if args.serve:
            from vtts.serve.server import Server, load_heads, warm_up

            server = Server(load_heads(["cybatt"]))
            warm_up(server)
            url = stack.enter_context(server.running())
        asyncio.run(feed(url, args.text, args.words, args.interval))


if __name__ == "__main__":
    main()
