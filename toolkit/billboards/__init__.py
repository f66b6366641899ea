"""Articulated billboards (source 000 §1, §3): fans, projective texturing, position score, seams."""

from toolkit.billboards.build import build_billboard, build_billboards, segment_outline
from toolkit.billboards.config import (PAIR_ANGLE_SIGMA, RGB_DIAGONAL, SEAM_DEPTH_M, BillboardConfig,
                                       ScoreConfig)
from toolkit.billboards.geometry import BillboardFrame, billboard_frame, segment_extent
from toolkit.billboards.model import Billboard, BillboardFan, BillboardModel
from toolkit.billboards.score import (PartScore, PositionScorer, View, evaluated_views, midway_camera,
                                      pair_weight)
from toolkit.billboards.seams import SeamMap, detect_seams, membership_of
from toolkit.billboards.warp import RenderInfo, Warp, render_view, warp_billboard, warp_texture

__all__ = ["Billboard", "BillboardFan", "BillboardModel", "BillboardConfig", "ScoreConfig", "PAIR_ANGLE_SIGMA",
           "SEAM_DEPTH_M", "RGB_DIAGONAL", "BillboardFrame", "billboard_frame", "segment_extent",
           "build_billboard", "build_billboards", "segment_outline", "PartScore", "PositionScorer", "View",
           "evaluated_views", "midway_camera", "pair_weight", "SeamMap", "detect_seams", "membership_of",
           "RenderInfo", "Warp", "render_view", "warp_billboard", "warp_texture"]
