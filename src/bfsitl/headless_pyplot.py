"""matplotlib's pyplot for every figure bfsitl draws (a flight, a scenario, a blackbox log).

matplotlib is imported here only, on first use and with the non-interactive Agg backend, so
a headless machine (CI, SSH) can write PNGs and nothing else in bfsitl pays for the import.
"""

from __future__ import annotations

from bfsitl.errors import ExtraMissingError


def load_pyplot():  # type: ignore[no-untyped-def]
    try:
        import matplotlib
    except ImportError as exc:
        raise ExtraMissingError(
            "plots need matplotlib, a dependency of bfsitl that is missing here: "
            "pip install matplotlib"
        ) from exc
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
