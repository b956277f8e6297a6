"""A process handle for tests of code that starts and stops processes (Gazebo, gz topic)."""

from __future__ import annotations


class FakeGazebo:
    """A process handle: exits with ``code`` after ``exit_after`` signals (None: never)."""

    def __init__(self, code: int | None = None, exit_after: int | None = 1) -> None:
        self.pid = 99
        self.code = code
        self.exit_after = exit_after
        self.signals: list[int] = []

    def poll(self) -> int | None:
        return self.code

    def wait(self, timeout_s: float) -> int | None:
        return self.code

    def signal_group(self, signum: int) -> None:
        self.signals.append(signum)
        if self.exit_after is not None and len(self.signals) >= self.exit_after:
            self.code = -signum
