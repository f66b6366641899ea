"""2D pose from silhouettes: descriptor, reference database, E_S query, building, user edits (source 000 §2.1).

See ``docs/stage1_silhouettes.md``.

``descriptor``  the 32 x 40 silhouette grid, bounding-box joint frame, flow descriptor, silhouette checks
``database``    :class:`SilhouetteDatabase`: reference silhouettes with 2D poses, one ``.npz`` file
``query``       the k best entries by E_S (eq. 1), with the temporal, Hausdorff and flow variants
``building``    rendering a database from the synthetic body, motions and BVH files; the cached default
``edits``       the user's joint corrections (claim 7)
``pipeline``    per frame: silhouettes -> candidates -> multi-view selection -> edits
"""

from toolkit.silhouettes.building import (
    DEFAULT_BUILD,
    DEFAULT_SEED,
    BuildConfig,
    ViewSpec,
    build_database,
    cache_dir,
    default_database,
    default_database_path,
    render_silhouettes,
    view_around,
)
from toolkit.silhouettes.database import (
    FORMAT_NAME,
    FORMAT_VERSION,
    USER_MOTION,
    DatabaseEntry,
    SilhouetteDatabase,
)
from toolkit.silhouettes.descriptor import (
    DESCRIPTOR_SIZE,
    SILHOUETTE_GRID,
    SILHOUETTE_STATES,
    SilhouetteCheck,
    bounding_box,
    check_silhouette,
    denormalise_joints,
    descriptor_grid,
    flow_descriptor,
    normalise_joints,
    quantise_descriptor,
    silhouette_descriptor,
    silhouette_grid,
)
from toolkit.silhouettes.edits import Edits, JointEdit, edits_template, parse_edits, read_edits
from toolkit.silhouettes.pipeline import (
    FRAME_STATES,
    FrameEstimate,
    SilhouettePoseEstimator,
    Stage1Config,
    estimate_dataset,
    stack_estimates,
)
from toolkit.silhouettes.query import (
    K_BEST,
    LAMBDA_TEMPORAL,
    Candidates,
    QueryConfig,
    hausdorff_distance,
    query_database,
    silhouette_distances,
)

__all__ = [
    "DEFAULT_BUILD", "DEFAULT_SEED", "BuildConfig", "ViewSpec", "build_database", "cache_dir", "default_database",
    "default_database_path",
    "render_silhouettes", "view_around",
    "FORMAT_NAME", "FORMAT_VERSION", "USER_MOTION", "DatabaseEntry", "SilhouetteDatabase",
    "DESCRIPTOR_SIZE", "SILHOUETTE_GRID", "SILHOUETTE_STATES", "SilhouetteCheck", "bounding_box",
    "check_silhouette", "denormalise_joints", "descriptor_grid", "flow_descriptor", "normalise_joints",
    "quantise_descriptor", "silhouette_descriptor", "silhouette_grid",
    "Edits", "JointEdit", "edits_template", "parse_edits", "read_edits",
    "FRAME_STATES", "FrameEstimate", "SilhouettePoseEstimator", "Stage1Config", "estimate_dataset",
    "stack_estimates",
    "K_BEST", "LAMBDA_TEMPORAL", "Candidates", "QueryConfig", "hausdorff_distance", "query_database",
    "silhouette_distances",
]
