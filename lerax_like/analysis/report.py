"""Moved: each study writes its own files, through `recording` (the one writer). The old imports
work and warn, naming the new place:

- the work-precision study's files: `lerax_like.analysis.study` (`write_study`, `write_json`,
  `write_csv`, `read_csv`, `CSV_COLUMNS`, `VERDICT_TARGETS`);
- the gradient study's: `lerax_like.analysis.gradient_accuracy` (`write_gradient_study`,
  `GRADIENT_CSV_COLUMNS`);
- the terminal tables: `lerax_like.analysis.tables`; the figures: `lerax_like.analysis.figures`;
  the verdicts: `lerax_like.analysis.verdict`; the plot hint: `lerax_like.analysis.recording`.
"""

from .._module_attributes import moved_names


__getattr__ = moved_names(__name__, {
    "lerax_like.analysis.study": (
        "CSV_COLUMNS", "VERDICT_TARGETS", "StudyResult", "read_csv", "write_csv", "write_json", "write_study",
    ),
    "lerax_like.analysis.gradient_accuracy": ("GRADIENT_CSV_COLUMNS", "write_gradient_study"),
    "lerax_like.analysis.tables": ("format_gradient_table", "format_orders", "format_table"),
    "lerax_like.analysis.figures": ("order_guide", "plot_gradient_work_precision", "plot_work_precision"),
    "lerax_like.analysis.verdict": (
        "UNRESOLVED_SPREAD", "UNRESOLVED_TIMING_FACTOR", "cheapest_at", "failures", "group_settings",
        "order_disagreements", "setting_name", "timing_unresolved",
    ),
    "lerax_like.analysis.recording": (
        "PLOT_HINT", "fixed_width_table", "matplotlib_available", "read_csv_rows", "write_record",
    ),
    "lerax_like.analysis.convergence": ("ORDER_DISAGREEMENT",),
})
