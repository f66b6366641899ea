"""Skeletons as data: joint names, parents, bones, symmetric pairs and body parts.

A body *part* is the volume around one bone; its two ends are convex
combinations of joints (the torso runs from the neck to the mid-hip point), so
``part_endpoints = part_weights @ joints`` for any joints array ``(..., J, 3)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.errors import InputError


@dataclass(frozen=True)
class Part:
    """A body part attached to a bone.

    Parameters
    ----------
    name : str
    proximal : dict[str, float]
        Joint weights of the part's proximal end (sum to 1).
    distal : dict[str, float]
        Joint weights of the distal end.
    """

    name: str
    proximal: dict
    distal: dict

    @property
    def joints(self) -> tuple[str, ...]:
        """Joints this part depends on."""
        return tuple(dict.fromkeys([*self.proximal, *self.distal]))


@dataclass(frozen=True)
class Skeleton:
    """A kinematic tree of named joints.

    Parameters
    ----------
    name : str
    joint_names : tuple of str
    parents : tuple of int
        Parent index per joint, -1 for the root.
    symmetric_bones : tuple of (int, int)
        Pairs of indices into :attr:`bones` that are left/right mirrors.
    parts : tuple of Part
        Body parts (one per rendered/segmented bone); part ids are 1-based
        in label images (0 = background).
    extra_edges : tuple of (str, str)
        Non-tree connections drawn for display (e.g. hip to hip).
    """

    name: str
    joint_names: tuple[str, ...]
    parents: tuple[int, ...]
    symmetric_bones: tuple[tuple[int, int], ...] = ()
    parts: tuple[Part, ...] = ()
    extra_edges: tuple[tuple[str, str], ...] = ()

    def __post_init__(self):
        if len(self.joint_names) != len(self.parents):
            raise InputError(f"skeleton {self.name}: parents", f"{len(self.joint_names)} entries",
                             f"{len(self.parents)}")
        if len(set(self.joint_names)) != len(self.joint_names):
            raise InputError(f"skeleton {self.name}: joint_names", "unique names", str(self.joint_names))

    # -------------------------------------------------------------- structure
    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @property
    def bones(self) -> tuple[tuple[int, int], ...]:
        """Tree edges as (parent, child) joint indices, in joint order."""
        return tuple((p, c) for c, p in enumerate(self.parents) if p >= 0)

    @property
    def bone_names(self) -> tuple[str, ...]:
        return tuple(f"{self.joint_names[a]}-{self.joint_names[b]}" for a, b in self.bones)

    @property
    def edges(self) -> tuple[tuple[int, int], ...]:
        """Bones plus display-only edges, as joint index pairs."""
        extra = tuple((self.index(a), self.index(b)) for a, b in self.extra_edges)
        return self.bones + extra

    def index(self, name: str) -> int:
        """Index of a joint by name."""
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise KeyError(f"skeleton {self.name} has no joint {name!r}; joints are {self.joint_names}") from None

    def indices(self, names) -> list[int]:
        return [self.index(n) for n in names]

    def children(self, joint: int) -> list[int]:
        return [c for c, p in enumerate(self.parents) if p == joint]

    @property
    def flip_permutation(self) -> np.ndarray:
        """Joint permutation that swaps left and right (``l_`` <-> ``r_`` names)."""
        perm = []
        for n in self.joint_names:
            if n.startswith("l_"):
                perm.append(self.index("r_" + n[2:]))
            elif n.startswith("r_"):
                perm.append(self.index("l_" + n[2:]))
            else:
                perm.append(self.index(n))
        return np.array(perm)

    # ------------------------------------------------------------------ parts
    @property
    def n_parts(self) -> int:
        return len(self.parts)

    @property
    def part_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parts)

    @property
    def part_weights(self) -> np.ndarray:
        """Matrix of shape (n_parts, 2, n_joints): ``W @ joints`` gives part end points."""
        W = np.zeros((self.n_parts, 2, self.n_joints))
        for i, part in enumerate(self.parts):
            for end, weights in enumerate((part.proximal, part.distal)):
                for jn, w in weights.items():
                    W[i, end, self.index(jn)] = w
        return W

    def part_endpoints(self, joints: np.ndarray) -> np.ndarray:
        """End points of every part.

        Parameters
        ----------
        joints : ndarray of shape (..., n_joints, D)

        Returns
        -------
        ndarray of shape (..., n_parts, 2, D)
        """
        j = np.asarray(joints, float)
        if j.shape[-2] != self.n_joints:
            raise InputError("joints", f"an array of shape (..., {self.n_joints}, D)", f"shape {j.shape}")
        return np.einsum("pej,...jd->...ped", self.part_weights, j)

    def parts_of_joint(self, joint: int) -> list[int]:
        """Indices of the parts whose end points depend on ``joint``."""
        W = self.part_weights
        return [i for i in range(self.n_parts) if np.any(W[i, :, joint] != 0)]

    def check_joints(self, joints: np.ndarray, name: str = "joints") -> np.ndarray:
        """Validate a ``(..., n_joints, D)`` array and return it as float."""
        j = np.asarray(joints, float)
        if j.ndim < 2 or j.shape[-2] != self.n_joints:
            raise InputError(name, f"an array of shape (..., {self.n_joints}, 2 or 3) for skeleton {self.name}",
                             f"shape {j.shape}")
        return j

    def bone_lengths(self, joints: np.ndarray) -> np.ndarray:
        """Bone lengths (..., n_bones) of joints (..., n_joints, 3)."""
        j = self.check_joints(joints)
        a, b = np.array(self.bones).T
        return np.linalg.norm(j[..., b, :] - j[..., a, :], axis=-1)


# --------------------------------------------------------------------------
# The 14-joint skeleton of the articulated-billboard system (source 000, §2.3)
# --------------------------------------------------------------------------
JOINTS_14 = ("head", "neck", "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow", "r_wrist",
             "l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle")
_PARENTS_14 = (1, -1, 1, 2, 3, 1, 5, 6, 1, 8, 9, 1, 11, 12)
_PELVIS = {"l_hip": 0.5, "r_hip": 0.5}

#: Body parts of the 14-joint skeleton; label ids are 1 + the index here.
PARTS_14 = (
    Part("head", {"neck": 1.0}, {"head": 1.0}),
    Part("torso", {"neck": 1.0}, _PELVIS),
    Part("l_upper_arm", {"l_shoulder": 1.0}, {"l_elbow": 1.0}),
    Part("l_forearm", {"l_elbow": 1.0}, {"l_wrist": 1.0}),
    Part("r_upper_arm", {"r_shoulder": 1.0}, {"r_elbow": 1.0}),
    Part("r_forearm", {"r_elbow": 1.0}, {"r_wrist": 1.0}),
    Part("l_thigh", {"l_hip": 1.0}, {"l_knee": 1.0}),
    Part("l_shank", {"l_knee": 1.0}, {"l_ankle": 1.0}),
    Part("r_thigh", {"r_hip": 1.0}, {"r_knee": 1.0}),
    Part("r_shank", {"r_knee": 1.0}, {"r_ankle": 1.0}),
)


def _bone(sk_joints, parents, a, b):
    bones = [(p, c) for c, p in enumerate(parents) if p >= 0]
    return bones.index((sk_joints.index(a), sk_joints.index(b)))


def _sym_pairs(joints, parents):
    pairs = []
    bones = [(p, c) for c, p in enumerate(parents) if p >= 0]
    for i, (p, c) in enumerate(bones):
        cn, pn = joints[c], joints[p]
        if cn.startswith("l_"):
            mc = "r_" + cn[2:]
            mp = "r_" + pn[2:] if pn.startswith("l_") else pn
            j = bones.index((joints.index(mp), joints.index(mc)))
            pairs.append((i, j))
    return tuple(pairs)


SKELETON_14 = Skeleton(
    name="billboard14",
    joint_names=JOINTS_14,
    parents=_PARENTS_14,
    symmetric_bones=_sym_pairs(JOINTS_14, _PARENTS_14),
    parts=PARTS_14,
    extra_edges=(("l_hip", "r_hip"), ("l_shoulder", "r_shoulder")),
)

# --------------------------------------------------------------------------
# Depth-tracking skeletons (source 001): 13 control points, 17-point variant
# --------------------------------------------------------------------------
JOINTS_13 = ("head", "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_hand", "r_hand",
             "l_hip", "r_hip", "l_knee", "r_knee", "l_foot", "r_foot")
_PARENTS_13 = (-1, 0, 0, 1, 2, 3, 4, 1, 2, 7, 8, 9, 10)
SKELETON_13 = Skeleton(
    name="depth13",
    joint_names=JOINTS_13,
    parents=_PARENTS_13,
    symmetric_bones=_sym_pairs(JOINTS_13, _PARENTS_13),
    extra_edges=(("l_shoulder", "r_shoulder"), ("l_hip", "r_hip"), ("l_shoulder", "r_hip"),
                 ("r_shoulder", "l_hip")),
)
#: The torso patch of 4 control points (source 001).
TORSO_PATCH_13 = ("l_shoulder", "r_shoulder", "r_hip", "l_hip")

JOINTS_17 = ("head", "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_wrist", "r_wrist",
             "l_hand", "r_hand", "l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle",
             "l_foot", "r_foot")
_PARENTS_17 = (-1, 0, 0, 1, 2, 3, 4, 5, 6, 1, 2, 9, 10, 11, 12, 13, 14)
SKELETON_17 = Skeleton(
    name="depth17",
    joint_names=JOINTS_17,
    parents=_PARENTS_17,
    symmetric_bones=_sym_pairs(JOINTS_17, _PARENTS_17),
    extra_edges=(("l_shoulder", "r_shoulder"), ("l_hip", "r_hip")),
)
