"""Turn a results directory into the paper's pictures and tables, beside the paper's own numbers."""

from train.experiments.report.pages import make_report

__all__ = ["make_report"]
