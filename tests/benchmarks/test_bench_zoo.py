"""The scene zoo draws valid specs that cover the space it promises (benchmarks/bench_zoo.py)."""

from __future__ import annotations

import numpy as np

from benchmarks import bench_zoo
from toolkit.motion import MOTIONS
from toolkit.synthetic import parse_spec


def test_zoo_covers_the_scene_space():
    specs = [parse_spec(text, f"{name}.toml") for name, text in bench_zoo.draw_specs(24, 13, 2)]
    assert len(specs) == 24
    quick = {(s.camera_count, s.layout) for s in specs[:bench_zoo.QUICK_SCENES]}
    assert quick == {(c, lay) for c in (2, 3, 4) for lay in ("broadcast", "studio")}
    assert {s.motion for s in specs} == set(MOTIONS) - {"rom"}    # rom: the marker labs' calibration trial
    assert {s.resolution for s in specs} == set(bench_zoo.RESOLUTIONS)
    assert any(s.outfit == "like_background" for s in specs[:bench_zoo.QUICK_SCENES])
    assert all(s.novel_placement == "around" and s.novel_count >= 3 for s in specs)
    lo = min(s.spacing_deg[0] for s in specs)
    hi = max(s.spacing_deg[1] for s in specs)
    assert lo >= 30.0 and lo < 45.0 and hi > 135.0 and hi <= 150.0
    px = [s.subject_px[0] for s in specs if s.subject_px is not None]
    assert min(px) >= 80 and max(px) <= 300 and max(px) - min(px) > 120
    err = [s.calibration_error_px for s in specs]
    assert min(err) >= 0 and max(err) <= 10 and np.ptp(err) > 5
    # the same seed draws the same zoo; another seed another one
    assert bench_zoo.draw_specs(24, 13, 2) == bench_zoo.draw_specs(24, 13, 2)
    assert bench_zoo.draw_specs(24, 14, 2) != bench_zoo.draw_specs(24, 13, 2)


def test_summary_flags_the_scenes_that_miss():
    def row(name, miou, art, std, hull, s1, s3, cov):
        return {"scene": name, "part_miou": miou, "psnr_articulated": art, "psnr_standard": std, "psnr_hull": hull,
                "margin_db": art - max(std, hull), "mpjpe_stage1_mm": s1, "mpjpe_mm": s3,
                "stage3_change": (s3 - s1) / s1, "coverage_min": cov}
    rows = [row("a", 0.9, 25.0, 20.0, 21.0, 30.0, 29.0, 0.99), row("b", 0.6, 15.0, 15.2, 14.0, 30.0, 35.0, 0.2)]
    s = bench_zoo.summary(rows)
    assert s["scenes_below_margin"] == ["b"] and s["scenes_below_coverage"] == ["b"]
    assert s["stage3_change"]["scenes_worse_than_3pct"] == ["b"]
    assert s["margin_share"] == 0.5 and s["coverage_min"] == 0.2
    assert abs(s["part_miou"]["median"] - 0.75) < 1e-12
