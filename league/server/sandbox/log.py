"""What sandboxes printed, kept within a size limit."""
from __future__ import annotations

import threading


class LogBuffer:
    """What sandboxes printed: the first and the last bytes of it, with a marker for the cut."""

    def __init__(self, limit: int):
        self.head_limit, self.tail_limit = limit // 4, limit - limit // 4
        self.head, self.tail, self.dropped = bytearray(), bytearray(), 0
        self._lock = threading.Lock()

    def write(self, data: bytes) -> None:
        with self._lock:
            room = self.head_limit - len(self.head)
            self.head += data[:room]
            self.tail += data[max(room, 0):]
            if len(self.tail) > self.tail_limit:
                self.dropped += len(self.tail) - self.tail_limit
                del self.tail[: len(self.tail) - self.tail_limit]

    def note(self, text: str) -> None:
        self.write(f"[sandbox] {text}\n".encode())

    def text(self) -> str:
        with self._lock:
            cut = f"\n[... {self.dropped} bytes cut ...]\n".encode() if self.dropped else b""
            return (bytes(self.head) + cut + bytes(self.tail)).decode("utf-8", errors="replace")
