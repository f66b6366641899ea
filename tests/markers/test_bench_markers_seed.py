"""bench_markers --seed: fresh scenes from a base seed."""

from __future__ import annotations

import pytest

from benchmarks.bench_markers import SCENES, main, seeded_scenes


def test_seeded_scenes_and_flags():
    assert seeded_scenes(71) == (("rom", "plug-in-gait", 71), ("rom", "plug-in-gait", 72),
                                 ("rom", "plug-in-gait", 73), ("rom", "cluster", 74),
                                 ("walk", "cluster", 81), ("walk", "plug-in-gait", 81))
    assert not {s for _, _, s in seeded_scenes(71)} & {s for _, _, s in SCENES}
    with pytest.raises(SystemExit):  # argparse's error: --seed with --quick
        main(["--seed", "71", "--quick"])
