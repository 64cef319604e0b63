"""The research pipeline on top of the trainer: the paper's experiments as data, sweeps, Table 1, reports."""
