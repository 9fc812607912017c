"""Which CPUs a job's thread and its sandboxes run on.

A sandbox answers each call over a pipe, and on a virtual machine waking a process on another
CPU is slow: a pipe round trip took ~55 us between the two CPUs of our 2-core VM, against ~8 us
on one. Hence:

* a job with one sandbox (validation, evaluation) is a ping-pong: its thread and the sandbox
  share one CPU (a 100-episode evaluation job: 8.6 s instead of 13.2 s, bench_server.py (c));
* a race asks every car at once, so its sandboxes may use all the CPUs of the thread's share;
* the job threads of one machine split its CPUs between them: each holds a slot, a locked file
  in a directory that every worker of the machine shares (`cpu_slots_dir`), and takes its
  block of the CPUs by its rank among the slots held; a thread alone takes them all. A lock
  dies with its process, so a crashed worker frees its slot.

Sandboxes run where the thread that starts them may run (league.server.sandbox.process.ForkServer
follows the thread's affinity), so placing the thread places its sandboxes.
"""
from __future__ import annotations

import fcntl
import logging
import os
import threading
from pathlib import Path

log = logging.getLogger("league.server.placement")
MAX_SLOTS = 1024


class CpuSlots:
    """Slots of job threads: held by this process (`claim`), counted machine-wide (`held`).
    Without a directory, only this process's slots count (its threads still split the CPUs)."""

    def __init__(self, folder: Path | str | None):
        self.folder = Path(folder) if folder else None
        self.mine: list[int] = []
        self._fds: list[int] = []  # the open files holding our slots' locks

    def claim(self, count: int) -> list[int]:
        """Hold `count` free slots for this process's life (all or none: OSError if not)."""
        if self.folder is None:
            self.mine = list(range(count))
            return self.mine
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            if self.folder.stat().st_uid == os.geteuid():
                os.chmod(self.folder, 0o1777)  # workers of other users on this machine share it
            for number in range(MAX_SLOTS):
                if len(self.mine) == count:
                    return self.mine
                if self._lock(number):
                    self.mine.append(number)
            raise OSError(f"no free CPU slot ({MAX_SLOTS} held)")
        except OSError:
            self.release()
            raise

    def _lock(self, number: int) -> bool:
        # read-only: flock needs no write access, so a slot file another user created is usable
        fd = os.open(self._path(number), os.O_RDONLY | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            return False
        self._fds.append(fd)
        return True

    def held(self) -> list[int]:
        """The slots held on this machine now, ours included."""
        if self.folder is None:
            return list(self.mine)
        numbers = sorted(int(name[5:]) for name in os.listdir(self.folder)
                         if name.startswith("slot-") and name[5:].isdigit())
        return [number for number in numbers if number in self.mine or self._is_held(number)]

    def release(self) -> None:
        for fd in self._fds:
            os.close(fd)
        self._fds.clear()
        self.mine.clear()

    def _is_held(self, number: int) -> bool:
        try:
            fd = os.open(self._path(number), os.O_RDONLY | os.O_CLOEXEC)
        except FileNotFoundError:
            return False
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return False
        except BlockingIOError:
            return True
        finally:
            os.close(fd)  # (and with it the lock we may have taken)

    def _path(self, number: int) -> Path:
        return self.folder / f"slot-{number}"


class Placement:
    """CPU placement of one worker process's job threads (see the module doc)."""

    def __init__(self, threads: int, slots_dir: Path | str | None, cpus: set[int] | None = None):
        self.cpus = sorted(cpus or os.sched_getaffinity(0))
        self.slots = CpuSlots(slots_dir)
        try:
            self.slots.claim(threads)
        except OSError as error:  # e.g. a directory we may not write to
            log.warning("CPU slots in %s unusable (%s): job threads split this worker's CPUs only", slots_dir, error)
            self.slots = CpuSlots(None)
            self.slots.claim(threads)
        self._unassigned = list(self.slots.mine)
        self._lock = threading.Lock()
        self._threads = threading.local()

    def place(self, parallel: bool) -> list[int]:
        """Pin the calling job thread (and so the sandboxes it starts) to its share of the CPUs,
        or to one CPU of it unless the job runs sandboxes in `parallel`. Returns the CPUs."""
        share = self.share()
        cpus = share if parallel else share[:1]
        os.sched_setaffinity(0, cpus)  # 0: the calling thread only
        return cpus

    def share(self) -> list[int]:
        """This thread's block of the CPUs, by its slot's rank among the slots held now."""
        slot = self._slot()
        held = self.slots.held()
        rank, count = held.index(slot), len(held)
        if count >= len(self.cpus):
            return [self.cpus[rank % len(self.cpus)]]
        size, extra = divmod(len(self.cpus), count)
        start = rank * size + min(rank, extra)
        return self.cpus[start:start + size + (rank < extra)]

    def close(self) -> None:
        self.slots.release()

    def _slot(self) -> int:
        slot = getattr(self._threads, "slot", None)
        if slot is None:
            with self._lock:  # a thread beyond those announced shares the last slot
                slot = self._unassigned.pop(0) if self._unassigned else self.slots.mine[-1]
            self._threads.slot = slot
        return slot
