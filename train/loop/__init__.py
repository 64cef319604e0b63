"""The training loop: `trainer` (K seeds of one condition, or several conditions of a task packed, in one
process), `parts` (one condition inside a trainer), `packing` (which conditions may share a learner), `memory`
(what a run will hold, refused before allocation when too much) and `runlog` (progress, metrics, visitation
counts, TensorBoard, the stop signal).
"""
