"""The pipe protocol's frames as the worker reads them (process.AnswerReader) and as the sandbox
reads requests and writes answers (child.Reader, child.Writer): split, joined, truncated,
oversized and garbage frames, over real pipes, with no sandbox."""
from __future__ import annotations

import os
import threading

import numpy as np
import pytest

from league.server.sandbox import child
from league.server.sandbox.process import ANSWER_BUFFER, MAX_MESSAGE, AnswerReader, Budget, SandboxFailure

HEADER, LENGTH = child.HEADER, child.LENGTH


class Pipe:
    """A pipe whose read end an AnswerReader reads; `kills` counts the reader's kills."""

    def __init__(self):
        self.read_fd, self.write_fd = os.pipe()
        self.kills = 0
        self.reader = AnswerReader(self.read_fd, lambda: "the sandbox process exited with code 1; see the log",
                                   self._kill)

    def _kill(self):
        self.kills += 1

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            view = view[os.write(self.write_fd, view):]

    def close_writer(self) -> None:
        os.close(self.write_fd)
        self.write_fd = None

    def close(self) -> None:
        os.close(self.read_fd)
        if self.write_fd is not None:
            os.close(self.write_fd)


@pytest.fixture
def pipe():
    p = Pipe()
    yield p
    p.close()


def budget(cpu_s: float = 5.0) -> Budget:
    return Budget(lambda: 0.0, cpu_s, cpu_s + 5.0)


def spent() -> Budget:
    """A budget with no CPU time left (the child's clock passed it)."""
    readings = iter([0.0])
    return Budget(lambda: next(readings, 10.0), 0.05, 60.0)


def action_frame(actions: np.ndarray) -> bytes:
    actions = np.ascontiguousarray(actions, dtype="<f4")
    return HEADER.pack(b"A", *actions.shape) + actions.tobytes()


def text_frame(tag: bytes, text: bytes) -> bytes:
    return tag + LENGTH.pack(len(text)) + text


def test_actions_in_one_piece_are_the_childs_numbers_in_a_copy_of_their_own(pipe):
    actions = np.array([[0.5, -0.25], [1.0, 0.125], [-1.0, 0.0]], dtype=np.float32)
    pipe.write(action_frame(actions))
    first = pipe.reader.actions(budget())
    np.testing.assert_array_equal(first, actions)
    assert first.dtype == np.float32 and first.flags.writeable and first.flags.owndata
    pipe.write(action_frame(-actions))
    np.testing.assert_array_equal(pipe.reader.actions(budget()), -actions)
    np.testing.assert_array_equal(first, actions)  # the buffer was reused, not the answer


def test_a_frame_split_anywhere_is_read_whole(pipe):
    actions = np.arange(8, dtype=np.float32).reshape(4, 2)
    frame = action_frame(actions)
    for cut in (1, 5, 9, 10, len(frame) - 1):
        writer = threading.Timer(0.05, pipe.write, [frame[cut:]])
        pipe.write(frame[:cut])
        writer.start()
        np.testing.assert_array_equal(pipe.reader.actions(budget()), actions)
        writer.join()


def test_frames_written_together_are_read_one_at_a_time(pipe):
    a, b = np.ones((2, 2), dtype=np.float32), np.zeros((1, 2), dtype=np.float32)
    pipe.write(action_frame(a) + text_frame(b"E", b"the model raised ValueError") + action_frame(b))
    np.testing.assert_array_equal(pipe.reader.actions(budget()), a)
    with pytest.raises(SandboxFailure) as failure:
        pipe.reader.actions(budget())
    assert failure.value.reason == "the model raised ValueError" and not failure.value.fatal
    np.testing.assert_array_equal(pipe.reader.actions(budget()), b)
    assert pipe.kills == 0


def test_many_frames_larger_than_the_buffer_in_all_are_read_in_order(pipe):
    rows = child.MAX_BATCH
    frames = [np.full((rows, 2), k, dtype=np.float32) for k in range(6)]  # 6 x 32 KB through a 128 KB buffer
    writer = threading.Thread(target=pipe.write, args=(b"".join(action_frame(f) for f in frames),))
    writer.start()
    for expected in frames:
        np.testing.assert_array_equal(pipe.reader.actions(budget()), expected)
    writer.join()


def test_a_truncated_frame_is_the_childs_death(pipe):
    pipe.write(action_frame(np.ones((3, 2), dtype=np.float32))[:-5])
    pipe.close_writer()
    with pytest.raises(SandboxFailure) as failure:
        pipe.reader.actions(budget())
    assert failure.value.fatal and "exited with code 1" in failure.value.reason


def test_a_truncated_header_is_the_childs_death(pipe):
    pipe.write(b"A\x03\x00")
    pipe.close_writer()
    with pytest.raises(SandboxFailure, match="exited with code 1") as failure:
        pipe.reader.actions(budget())
    assert failure.value.fatal


@pytest.mark.parametrize("frame, what", [
    (HEADER.pack(b"A", child.MAX_BATCH + 1, 2), r"actions 4097x2"),
    (HEADER.pack(b"A", 2**32 - 1, 2), r"actions 4294967295x2"),
    (HEADER.pack(b"A", 3, 3) + bytes(36), r"actions 3x3"),
    (HEADER.pack(b"A", 3, 0), r"actions 3x0"),
    (b"E" + LENGTH.pack(MAX_MESSAGE + 1) + b"x" * 100, r"message too long"),
    (b"E" + LENGTH.pack(2**32 - 1), r"message too long"),
    (b"R" + LENGTH.pack(2) + b"{}", r"message b'R'"),
    (b"\x00garbage", r"message b'\\x00'"),
])
def test_an_oversized_or_unknown_frame_kills_the_child(pipe, frame, what):
    pipe.write(frame)
    with pytest.raises(SandboxFailure, match=f"sandbox protocol error \\({what}\\)") as failure:
        pipe.reader.actions(budget())
    assert failure.value.fatal and pipe.kills == 1


def test_a_flood_of_garbage_is_a_protocol_error_not_a_read_of_it_all(pipe):
    writer = threading.Thread(target=lambda: pipe.write(b"Z" * (ANSWER_BUFFER * 4)), daemon=True)
    writer.start()
    with pytest.raises(SandboxFailure, match="sandbox protocol error"):
        pipe.reader.actions(budget())
    assert pipe.kills == 1
    os.set_blocking(pipe.read_fd, False)  # let the writer end
    while True:
        try:
            if not os.read(pipe.read_fd, 1 << 16):
                break
        except BlockingIOError:
            if not writer.is_alive():
                break
    writer.join(timeout=5)


def test_a_text_frame_of_the_largest_size_is_read(pipe):
    text = "é".encode() * (MAX_MESSAGE // 2)
    writer = threading.Thread(target=pipe.write, args=(text_frame(b"E", text),))
    writer.start()
    with pytest.raises(SandboxFailure) as failure:
        pipe.reader.actions(budget())
    writer.join()
    assert not failure.value.fatal and failure.value.reason.startswith("éé") and pipe.kills == 0


def test_no_answer_within_the_cpu_budget_is_a_timeout(pipe):
    with pytest.raises(SandboxFailure) as failure:
        pipe.reader.actions(spent())
    assert failure.value.timed_out and failure.value.fatal and pipe.kills == 1


def test_half_an_answer_within_the_budget_is_a_timeout(pipe):
    pipe.write(action_frame(np.ones((3, 2), dtype=np.float32))[:12])
    with pytest.raises(SandboxFailure) as failure:
        pipe.reader.actions(spent())
    assert failure.value.timed_out and pipe.kills == 1


def test_the_ready_message_and_a_load_failure(pipe):
    pipe.write(text_frame(b"R", b'{"obs_dim": 5}') + text_frame(b"E", b"no"))
    assert pipe.reader.message(budget(), expected=(b"R", b"E")) == (b"R", b'{"obs_dim": 5}')
    assert pipe.reader.message(budget(), expected=(b"R", b"E")) == (b"E", b"no")


# --------------------------------------------------------------------------- the sandbox's side


def test_the_childs_reader_reads_requests_split_joined_and_larger_than_its_buffer():
    read_fd, write_fd = os.pipe()
    try:
        reader = child.Reader(read_fd, size=64)
        small = np.arange(10, dtype="<f4").reshape(2, 5)
        big = np.arange(child.MAX_BATCH * 20, dtype="<f4").reshape(child.MAX_BATCH, 20)
        frames = [HEADER.pack(b"I", *a.shape) + a.tobytes() for a in (small, small * 2, big)]
        writer = threading.Thread(target=lambda: [os.write(write_fd, b"".join(frames)[k:k + 1000])
                                                  for k in range(0, len(b"".join(frames)), 1000)])
        writer.start()
        for expected in (small, small * 2, big):
            assert reader.fill(HEADER.size)
            tag, n, d = HEADER.unpack_from(reader.buffer, reader.start)
            assert (tag, n, d) == (b"I", *expected.shape)
            reader.consume(HEADER.size)
            np.testing.assert_array_equal(np.frombuffer(reader.read_exact(4 * n * d), dtype="<f4").reshape(n, d),
                                          expected)
        writer.join()
        os.close(write_fd)
        write_fd = None
        assert not reader.fill(1) and reader.read_exact(1) == b""
    finally:
        os.close(read_fd)
        if write_fd is not None:
            os.close(write_fd)


def test_the_childs_writer_sends_one_frame_per_answer():
    read_fd, write_fd = os.pipe()
    try:
        writer = child.Writer(write_fd)
        for rows in (1, 3, child.MAX_BATCH):
            actions = np.linspace(-1, 1, 2 * rows, dtype=np.float32).reshape(rows, 2)
            threading.Thread(target=writer.actions, args=(actions,)).start()
            data = b""
            while len(data) < HEADER.size + 8 * rows:
                data += os.read(read_fd, 1 << 16)
            assert data == action_frame(actions)
    finally:
        os.close(read_fd)
        os.close(write_fd)
