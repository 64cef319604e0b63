"""Compiled kernels for different grid sizes can share one process, whichever process cached them."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

MANGLE = textwrap.dedent("""
    import sys
    import numba, numpy as np
    from gridtasks import engine
    for n in map(int, sys.argv[1:]):  # create record types in this order: numba's own counter follows it
        numba.typeof(np.zeros(1, engine.world_dtype(n))[0])
    print(numba.typeof(np.zeros(1, engine.world_dtype(8))[0]).mangling_args)
""")


def mangled(*sizes: int) -> str:
    out = subprocess.run([sys.executable, "-c", MANGLE, *map(str, sizes)], capture_output=True, text=True,
                         check=True)
    return out.stdout.strip()


def test_a_record_type_is_mangled_the_same_in_every_process():
    # numba's default names record types by a per-process counter; two processes that create their types
    # in different orders would then give the 8x8 world different names, and different records the same
    assert mangled(5, 8) == mangled(8) == mangled(10, 7, 8)


def test_different_grid_sizes_are_mangled_differently():
    import numba
    import numpy as np

    from gridtasks import engine

    names = {numba.typeof(np.zeros(1, engine.world_dtype(n))[0]).mangling_args for n in (5, 7, 8, 10)}
    assert len(names) == 4


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_kernels_cached_by_separate_processes_load_together(tmp_path):
    # each size compiled (and cached) by its own process, then all loaded by one: crashed in LLVM before
    run = "import gridtasks\nfor n in ({}):\n    e = gridtasks.SaladEnv(grid_size=n); e.reset(seed=0); e.step(4)\n"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    for n in (5, 6, 7):
        subprocess.run([sys.executable, "-c", run.format(f"{n},")], check=True, env=env, timeout=600)
    subprocess.run([sys.executable, "-c", run.format("7, 6, 5")], check=True, env=env, timeout=600)
