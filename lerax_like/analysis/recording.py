"""The one writer of studies and benchmarks: CSV rows, JSON records, figures, terminal tables.

Every study of `lerax_like.analysis` and every script under `benchmarks/` writes through
these functions, so that a CSV cell, a JSON number and a figure file are written one way:
NaN as an empty CSV cell, arrays and NumPy scalars as JSON lists and numbers, figures as
PNG at one resolution, closed once saved. Matplotlib is optional: `pyplot()` raises with
the install hint, `matplotlib_available()` asks without raising.
"""

import csv
import importlib.metadata
import json
import math
import os
import platform
from collections.abc import Iterable, Sequence
from typing import Any


PLOT_HINT = "pip install 'lerax_like[study]' (or pip install matplotlib)"
FIGURE_DPI = 110


def csv_cell(value: Any) -> Any:
    """A value as a CSV cell: NaN as an empty cell (a value not measured), a float in full precision."""
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return value


def write_csv(
    rows: Iterable[dict[str, Any]], path: "str | os.PathLike", *, columns: Sequence[str] | None = None,
    cell=csv_cell,
) -> None:
    """Write `rows` with a header of `columns` (default: the first row's keys, in order).

    Keys outside `columns` are left out; a missing key is an empty cell. `cell` formats
    each value (default `csv_cell`).
    """
    rows = list(rows)
    if columns is None:
        columns = list(rows[0]) if rows else []
    with open(path, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({key: cell(row.get(key, "")) for key in columns})


def read_csv_rows(path: "str | os.PathLike") -> list[dict[str, str]]:
    """The rows of a CSV file as strings, by column name."""
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def json_default(value: Any) -> Any:
    """NumPy scalars as numbers, NumPy and JAX arrays as (nested) lists, for `json.dump`."""
    try:
        import numpy as np
    except ImportError:  # pragma: no cover
        raise TypeError(f"not JSON serialisable: {value!r}") from None
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray) or hasattr(value, "__array__"):  # JAX arrays too
        return np.asarray(value).tolist()
    raise TypeError(f"not JSON serialisable: {value!r}")


def write_record(record: dict[str, Any], path: "str | os.PathLike") -> None:
    """Write a JSON record (indented; NaN allowed, as Python's `json` writes it)."""
    with open(path, "w") as file:
        json.dump(record, file, indent=1, default=json_default, allow_nan=True)
        file.write("\n")


def environment_record() -> dict[str, Any]:
    """Library versions and the machine, for the JSON record of a study or benchmark."""
    import jax

    versions = {}
    for package in ("lerax_like", "jax", "jaxlib", "diffrax", "equinox", "numpy", "scipy", "matplotlib"):
        try:
            versions[package] = importlib.metadata.version(package)
        except importlib.metadata.PackageNotFoundError:
            # Not installed (lerax_like itself too, when run from a source tree it was never
            # installed from): no version to record, said as null rather than guessed.
            versions[package] = None
    processor = platform.processor()
    try:
        with open("/proc/cpuinfo") as cpuinfo:
            for line in cpuinfo:
                if line.startswith("model name"):
                    processor = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {
        "python": platform.python_version(),
        "versions": versions,
        "platform": platform.platform(),
        "processor": processor,
        "cpu_count": os.cpu_count(),
        "jax_backend": jax.default_backend(),
        "jax_devices": [str(device) for device in jax.devices()],
    }


def pyplot():
    """`matplotlib.pyplot` on a non-interactive backend; an ImportError with the install hint without it."""
    try:
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt
    except ImportError as error:
        raise ImportError(f"plots need matplotlib: {PLOT_HINT}") from error
    return plt


def matplotlib_available() -> bool:
    """Whether matplotlib can be imported (plots are optional)."""
    try:
        pyplot()
    except ImportError:
        return False
    return True


def save_figure(figure, path: "str | os.PathLike | None"):
    """Save `figure` as PNG and release it when `path` is given; return it either way."""
    if path is not None:
        figure.savefig(path, dpi=FIGURE_DPI)
        pyplot().close(figure)
    return figure


def finish_figure(figure, title: str, path: "str | os.PathLike | None"):
    """Title and lay out `figure`, then `save_figure`."""
    figure.suptitle(title)
    figure.tight_layout()
    return save_figure(figure, path)


def fixed_width_table(header: Sequence[str], lines: Iterable[Sequence[str]]) -> str:
    """Left-aligned columns two spaces apart, for the terminal."""
    lines = [tuple(header)] + [tuple(line) for line in lines]
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    return "\n".join("  ".join(cell.ljust(width) for cell, width in zip(line, widths)).rstrip() for line in lines)
