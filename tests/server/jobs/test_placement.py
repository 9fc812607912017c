"""CPU placement of job threads and their sandboxes: real locks in a real directory, real
processes, the affinities the kernel reports."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading

import pytest

from league.server.jobs.placement import CpuSlots, Placement

from ...layout import REPO

CPUS = sorted(os.sched_getaffinity(0))
needs_two_cpus = pytest.mark.skipif(len(CPUS) < 2, reason="placement splits CPUs: this process may use one")


def in_thread(function):
    """Run `function` in a new thread (placement pins the calling thread: never the test's)."""
    result = []
    thread = threading.Thread(target=lambda: result.append(function()))
    thread.start()
    thread.join()
    return result[0]


def test_cpus_are_split_in_blocks_by_the_rank_of_each_slot(tmp_path):
    eight = set(range(8))
    placements = [Placement(1, tmp_path, cpus=eight) for _ in range(3)]
    assert [in_thread(p.share) for p in placements] == [[0, 1, 2], [3, 4, 5], [6, 7]]
    placements[1].close()  # its worker stopped: the others take its CPUs
    assert [in_thread(p.share) for p in (placements[0], placements[2])] == [[0, 1, 2, 3], [4, 5, 6, 7]]
    placements[0].close()
    placements[2].close()
    more = [Placement(1, tmp_path, cpus={0, 1}) for _ in range(3)]  # more threads than CPUs: they wrap
    assert [in_thread(p.share) for p in more] == [[0], [1], [0]]


@needs_two_cpus
def test_job_threads_of_one_machine_take_cpus_of_their_own(tmp_path):
    first, second = Placement(1, tmp_path), Placement(1, tmp_path)  # two worker processes' slots
    assert CpuSlots(tmp_path).held() == [0, 1]
    shares = [in_thread(first.share), in_thread(second.share)]
    assert not set(shares[0]) & set(shares[1]) and sorted(shares[0] + shares[1]) == CPUS
    second.close()
    assert in_thread(first.share) == CPUS  # alone again: every CPU


@needs_two_cpus
def test_the_slot_of_a_killed_worker_is_free_at_once(tmp_path):
    mine = Placement(1, tmp_path)
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time; from league.server.jobs.placement import Placement; "
                               f"p = Placement(1, {str(tmp_path)!r}); print('held', flush=True); time.sleep(60)"],
        cwd=REPO, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        assert CpuSlots(tmp_path).held() == [0, 1] and len(in_thread(mine.share)) < len(CPUS)
        holder.send_signal(signal.SIGKILL)
        holder.wait(timeout=10)
    finally:
        holder.kill()
        holder.stdout.close()
    assert CpuSlots(tmp_path).held() == [0] and in_thread(mine.share) == CPUS


@needs_two_cpus
def test_without_a_shared_directory_the_threads_of_one_worker_split_its_cpus():
    placement = Placement(2, None)
    shares = [in_thread(placement.share), in_thread(placement.share)]
    assert sorted(shares[0] + shares[1]) == CPUS and not set(shares[0]) & set(shares[1])


@needs_two_cpus
def test_a_job_with_one_sandbox_runs_on_one_cpu_and_a_race_on_the_threads_share(tmp_path):
    placement = Placement(1, tmp_path)

    def placed(parallel: bool):
        cpus = placement.place(parallel)
        return cpus, sorted(os.sched_getaffinity(0))

    assert in_thread(lambda: placed(False)) == ([CPUS[0]], [CPUS[0]])
    assert in_thread(lambda: placed(True)) == (CPUS, CPUS)
    assert sorted(os.sched_getaffinity(0)) == CPUS  # the test's own thread was left alone


def test_an_unusable_slots_directory_falls_back_to_the_workers_own_threads(tmp_path):
    blocked = tmp_path / "a-file"
    blocked.write_text("not a directory")
    placement = Placement(2, blocked)
    assert placement.slots.folder is None and placement.slots.held() == [0, 1]


def test_a_worker_that_cannot_claim_all_its_slots_holds_none(tmp_path):
    (tmp_path / "slot-1").symlink_to(tmp_path / "missing" / "slot")  # slot 1 cannot be created
    placement = Placement(2, tmp_path)
    assert placement.slots.folder is None and placement.slots.held() == [0, 1]  # fell back to its own threads
    assert CpuSlots(tmp_path).held() == []  # slot 0, claimed first, was let go
