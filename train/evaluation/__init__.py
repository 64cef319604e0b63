"""How trained agents are measured.

* `protocol`: the paper's evaluation (every agent of a run on the fixed validation layouts, in one batch);
* `grid`: a policy's success across epsilons, horizons and layout sets, split by what its first view holds.
"""
