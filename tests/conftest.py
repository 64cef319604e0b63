"""Progress a person can read, and the slowest test files first.

Every 30 s a line with the tests done, the failures so far and the time taken.

pytest's own ``-q`` output is a line of dots per 72 tests; with ``-n`` workers (pytest-xdist) that is all it prints
for minutes at a time. The line comes from the process that collects the reports, so it counts every worker's.
"""

from __future__ import annotations

import time

import pytest

STATUS_EVERY_S = 30.0
"""Seconds between two status lines."""


class Progress:
    """Counts finished tests and prints a status line at most every `STATUS_EVERY_S` seconds."""

    def __init__(self, config: pytest.Config) -> None:
        self.config = config
        self.started = time.monotonic()
        self.last = self.started
        self.done = self.failed = 0
        self.total = 0

    def pytest_collection_finish(self, session: pytest.Session) -> None:
        self.total = len(session.items)

    @pytest.hookimpl(optionalhook=True)  # pytest-xdist's hook: the workers' collections
    def pytest_xdist_node_collection_finished(self, node, ids) -> None:
        self.total = max(self.total, len(ids))

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        if report.when == "call" or (report.when == "setup" and report.outcome != "passed"):
            self.done += 1
            self.failed += report.outcome == "failed"
        now = time.monotonic()
        if now - self.last >= STATUS_EVERY_S:
            self.last = now
            minutes, seconds = divmod(int(now - self.started), 60)
            total = f" of {self.total}" if self.total else ""
            failed = f", {self.failed} failed" if self.failed else ""
            reporter = self.config.pluginmanager.get_plugin("terminalreporter")
            if reporter is not None:  # on a line of its own, between two lines of dots
                reporter.write(f"\n  ... {self.done}{total} tests done{failed}, {minutes} min {seconds:02d} s\n")


SLOW_FILES = (
    "tests/train/experiments/test_exp_smoke.py",  # trains every experiment at the smoke budget first
    "tests/train/experiments/test_exp_interrupt.py",
    "tests/train/test_train_hostile_files.py",
    "tests/train/experiments/test_exp_ray.py",
    "tests/benchmarks/test_gpu_run_script.py",
    "tests/train/test_train_kill_writes.py",
    "tests/train/test_train_resume.py",
    "tests/train/experiments/test_exp_merge.py",
    "tests/train/experiments/test_exp_report_pages.py",
    "tests/train/test_train_hostile_checkpoint.py",
)
"""The test files that take longest, slowest first: they are handed out first, so that with one worker per core
(``-n auto --dist loadfile``) the quick files fill the gaps instead of one long file running alone at the end."""


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Put the tests of `SLOW_FILES` first, in that order; every other test keeps its place after them."""
    order = {name: rank for rank, name in enumerate(SLOW_FILES)}
    items.sort(key=lambda item: order.get(item.nodeid.split("::")[0], len(order)))


def pytest_configure(config: pytest.Config) -> None:
    """Register the status lines on the process that reports (the controller, with xdist)."""
    if not hasattr(config, "workerinput"):
        config.pluginmanager.register(Progress(config), "ecorl-progress")
