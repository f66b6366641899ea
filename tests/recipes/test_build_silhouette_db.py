"""recipes/build_silhouette_db.py options from a TOML file: the [build] table, flags win, unknown keys refused."""

from __future__ import annotations

import importlib

from toolkit.silhouettes import SilhouetteDatabase


def load_recipe():
    return importlib.import_module("recipes.build_silhouette_db")


def test_config_file_flags_win_and_unknown_keys_are_refused(tmp_path, capsys):
    recipe = load_recipe()
    cfg = tmp_path / "db.toml"
    cfg.write_text('seed = 7\nworkers = 1\n[build]\nmotions = ["kick", "walk"]\nsequences_per_motion = 1\n'
                   'frames_per_sequence = 10\nframe_stride = 5\nviews_per_pose = 3\nmirror = false\n')
    out = tmp_path / "db.npz"
    assert recipe.main(["--out", str(out), "--config", str(cfg), "--motions", "kick", "--quiet"]) == 0
    db = SilhouetteDatabase.load(out)
    assert len(db) == 2 * 3 and set(db.motion.tolist()) == {"kick"}        # the flag's motions, the file's views
    args = recipe.parser().parse_args(["--out", "x.npz", "--config", str(cfg), "--flow", "--seed", "9"])
    c = recipe.config_from_args(args)
    assert c.seed == 9 and c.workers == 1 and c.build.with_flow and not c.build.mirror and c.build.views_per_pose == 3
    capsys.readouterr()
    cfg.write_text("[build]\nviews = 3\n")
    assert recipe.main(["--out", str(out), "--config", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert f"{cfg}: build.views" in err and "views_per_pose" in err
