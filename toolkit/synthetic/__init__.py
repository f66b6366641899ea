"""Synthetic multi-camera scenes of a moving person (or several players) with exact ground truth."""

from toolkit.body.model import BodyMesh, BodyModel, BodyShape
from toolkit.synthetic.environment import make_environment
from toolkit.synthetic.generator import Scene, build_scene, generate_scene
from toolkit.synthetic.players import Player, players_zoo
from toolkit.synthetic.render import Raycaster, RaycastRenderer, SceneRenderer
from toolkit.synthetic.rigs import make_rig, novel_rig, perturb_rig
from toolkit.synthetic.spec import PlayersSpec, SceneSpec, load_spec, parse_spec

__all__ = ["BodyMesh", "BodyModel", "BodyShape", "make_environment", "Scene", "build_scene", "generate_scene",
           "Raycaster", "RaycastRenderer", "SceneRenderer", "make_rig", "novel_rig", "perturb_rig", "SceneSpec", "load_spec",
           "parse_spec", "Player", "PlayersSpec", "players_zoo"]
