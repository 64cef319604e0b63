"""What a run keeps on disk, and how it is written and read back.

* `fileio`: every write (atomic replacement, fsync) and the advisory locks;
* `safeio`: reading files anyone may have crafted (regular files only, bounded, no links);
* `checkpoint`: the checkpoint file format (data only, never code) and `statecheck`, the checks on its values
  before any of them reaches torch, numpy's generators or the engine;
* `rundir`: a run directory's layout: resolved config, metrics, visitation counts, checkpoint.
* `policy`: policy files (one seed's network and its config, small enough to ship) and reading a policy
  from a run.

The package itself imports none of its modules, and no torch.
"""
