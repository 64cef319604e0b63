"""Turn a results directory into the paper's pictures and tables, beside the paper's own numbers.

`make_report` (in `pages`) reads the runs (`runs`), computes the statistics (`stats`) and tables (`tables`)
beside the paper's numbers (`paper`), draws the figures (`figures`), re-encodes the videos for browsers
(`webvideo`) and writes ``report.md`` and ``index.html``.
"""

from train.experiments.report.pages import make_report

__all__ = ["make_report"]
