"""The body-model asset: its arrays, validated, read from hkpd's ``.npz`` or from an SMPL file.

The format is specified in ``docs/body_asset_format.md``. :func:`load_body_asset` reads

- hkpd's own ``.npz`` (what :func:`save_body_asset` writes), or
- an SMPL model file (``.pkl`` or ``.npz``) with SMPL's standard fields, converted on load.

SMPL's ``.pkl`` files are Python-2 pickles holding chumpy objects and scipy sparse matrices. They
are read with a restricted unpickler that only builds numpy arrays, scipy sparse matrices and a
stand-in for chumpy arrays (chumpy itself is not needed); anything else is refused, so loading a
file never runs code it names.
"""

from __future__ import annotations

import io
import json
import pickle
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hkpd.coco_keypoints import COCO17_NAMES
from hkpd.kinematic_tree import SMPL_JOINT_NAMES, validate_parents
from hkpd.stated_body import SEX_NAMES

NUM_JOINTS = 24
"""Joints of the kinematic tree (SMPL's 24)."""

COCO_KEYPOINT_NAMES: tuple[str, ...] = COCO17_NAMES
"""The 17 COCO keypoints, in the order of the ``keypoint_regressor`` rows."""

WEIGHT_SUM_TOLERANCE = 1e-3
"""How far a row of skinning weights (or of the keypoint regressor) may sum from 1."""

REQUIRED_FIELDS = (
    "v_template",
    "faces",
    "shapedirs",
    "joint_template",
    "joint_shapedirs",
    "skinning_weights",
    "parents",
    "joint_names",
    "part_labels",
    "part_names",
)
"""Keys that an hkpd ``.npz`` must contain."""

OPTIONAL_FIELDS = (
    "keypoint_regressor",
    "posedirs",
    "sex_shape_means",
    "sex_shape_covariances",
    "metadata",
)
"""Keys that an hkpd ``.npz`` may contain (others are ignored)."""

SMPL_FIELDS = (
    "v_template",
    "shapedirs",
    "posedirs",
    "J_regressor",
    "weights",
    "kintree_table",
    "f",
)
"""Keys of an SMPL model file that the conversion reads."""

DEFAULT_SMPL_BETAS = 10
"""Shape coefficients kept from an SMPL file unless asked otherwise."""


@dataclass(frozen=True, eq=False)
class BodyAsset:
    """The arrays of a body model (see ``docs/body_asset_format.md``), validated on creation.

    Units are metres; the rest pose is a T-pose in SMPL axes. Floating arrays are stored as
    float32 and index arrays as int32 (``part_labels``: uint8) whatever they were given as.

    Attributes:
        v_template: ``(V, 3)`` rest vertices of the mean shape.
        faces: ``(F, 3)`` triangle vertex indices, counter-clockwise seen from outside.
        shapedirs: ``(V, 3, K)`` shape directions (metres per unit beta).
        joint_template: ``(24, 3)`` rest joints of the mean shape.
        joint_shapedirs: ``(24, 3, K)`` joint shape directions.
        skinning_weights: ``(V, 24)`` non-negative, each row summing to 1.
        parents: ``(24,)`` parent of each joint, -1 for the root (joint 0).
        joint_names: 24 joint names.
        part_labels: ``(V,)`` body part of each vertex, an index into ``part_names``.
        part_names: 24 part names.
        keypoint_regressor: ``(17, V)`` COCO keypoints from posed vertices, or None.
        posedirs: ``(V, 3, 9 * 23)`` pose-corrective blend shapes, or None.
        sex_shape_means: ``(2, K)`` mean shape coefficients of the female and the male
            population (rows in :data:`SEX_NAMES` order), or None (a model without sex priors).
        sex_shape_covariances: ``(2, K, K)`` their covariances (symmetric positive definite),
            given together with ``sex_shape_means``.
        metadata: JSON text describing the source.
        source: where the arrays came from (used in error messages; not saved).
    """

    v_template: np.ndarray
    faces: np.ndarray
    shapedirs: np.ndarray
    joint_template: np.ndarray
    joint_shapedirs: np.ndarray
    skinning_weights: np.ndarray
    parents: np.ndarray
    joint_names: tuple[str, ...]
    part_labels: np.ndarray
    part_names: tuple[str, ...]
    keypoint_regressor: np.ndarray | None = None
    posedirs: np.ndarray | None = None
    sex_shape_means: np.ndarray | None = None
    sex_shape_covariances: np.ndarray | None = None
    metadata: str = "{}"
    source: str = "BodyAsset"

    def __post_init__(self) -> None:
        check = _FieldChecker(self.source)
        set_field = object.__setattr__  # the dataclass is frozen; normalise once here

        v_template = check.floats("v_template", self.v_template, ("V", 3))
        vertices = v_template.shape[0]
        if vertices == 0:
            raise check.error("v_template", "has no vertices")
        shapedirs = check.floats("shapedirs", self.shapedirs, (vertices, 3, "K"))
        betas = shapedirs.shape[2]
        set_field(self, "v_template", v_template)
        set_field(self, "shapedirs", shapedirs)
        set_field(self, "faces", check.indices("faces", self.faces, ("F", 3), vertices))
        set_field(
            self,
            "joint_template",
            check.floats("joint_template", self.joint_template, (NUM_JOINTS, 3)),
        )
        set_field(
            self,
            "joint_shapedirs",
            check.floats("joint_shapedirs", self.joint_shapedirs, (NUM_JOINTS, 3, betas)),
        )
        weights = check.floats("skinning_weights", self.skinning_weights, (vertices, NUM_JOINTS))
        check.rows_sum_to_one("skinning_weights", weights, non_negative=True)
        set_field(self, "skinning_weights", weights)

        parents = check.integers("parents", self.parents, (NUM_JOINTS,))
        try:
            validate_parents(parents.tolist())
        except ValueError as problem:
            raise check.error("parents", str(problem)) from None
        if parents[0] != -1 or (parents[1:] == -1).any():
            raise check.error("parents", "must have exactly one root, joint 0 (parent -1)")
        set_field(self, "parents", parents.astype(np.int32))

        set_field(self, "joint_names", check.names("joint_names", self.joint_names, NUM_JOINTS))
        part_names = check.names("part_names", self.part_names, NUM_JOINTS)
        set_field(self, "part_names", part_names)
        labels = check.indices("part_labels", self.part_labels, (vertices,), len(part_names))
        set_field(self, "part_labels", labels.astype(np.uint8))

        if self.keypoint_regressor is not None:
            regressor = check.floats(
                "keypoint_regressor", self.keypoint_regressor, (len(COCO_KEYPOINT_NAMES), vertices)
            )
            check.rows_sum_to_one("keypoint_regressor", regressor, non_negative=False)
            set_field(self, "keypoint_regressor", regressor)
        if self.posedirs is not None:
            pose_features = 9 * (NUM_JOINTS - 1)
            set_field(
                self,
                "posedirs",
                check.floats("posedirs", self.posedirs, (vertices, 3, pose_features)),
            )
        self._check_sex_priors(check, betas)
        if not isinstance(self.metadata, str):
            raise check.error("metadata", f"must be a JSON string, got {type(self.metadata)}")

    def _check_sex_priors(self, check: _FieldChecker, betas: int) -> None:
        """Validate (and normalise) the optional sex-specific shape priors: both or neither,
        ``(2, K)`` means and ``(2, K, K)`` symmetric positive-definite covariances."""
        means, covariances = self.sex_shape_means, self.sex_shape_covariances
        if means is None and covariances is None:
            return
        if means is None or covariances is None:
            raise check.error(
                "sex_shape_means" if means is None else "sex_shape_covariances",
                "must be given together with its partner field (sex-specific shape priors)",
            )
        count = len(SEX_NAMES)
        means = check.floats("sex_shape_means", means, (count, betas))
        covariances = check.floats("sex_shape_covariances", covariances, (count, betas, betas))
        if not np.allclose(covariances, covariances.transpose(0, 2, 1), atol=1e-5):
            raise check.error("sex_shape_covariances", "must be symmetric")
        if (np.linalg.eigvalsh(covariances.astype(np.float64)) <= 0).any():
            raise check.error("sex_shape_covariances", "must be positive definite")
        object.__setattr__(self, "sex_shape_means", means)
        object.__setattr__(self, "sex_shape_covariances", covariances)

    @property
    def num_vertices(self) -> int:
        """V."""
        return int(self.v_template.shape[0])

    @property
    def num_betas(self) -> int:
        """K, the number of shape coefficients."""
        return int(self.shapedirs.shape[2])

    @property
    def info(self) -> dict[str, Any]:
        """``metadata`` parsed from JSON (empty if it is not valid JSON)."""
        try:
            parsed = json.loads(self.metadata)
        except json.JSONDecodeError:
            return {}
        return parsed if isinstance(parsed, dict) else {}


class _FieldChecker:
    """Shape/dtype checks that raise ``ValueError`` naming the file and the field."""

    def __init__(self, source: str) -> None:
        self.source = source

    def error(self, field: str, problem: str) -> ValueError:
        return ValueError(f"{self.source}: field '{field}' {problem}")

    def shaped(self, field: str, value: Any, shape: tuple[int | str, ...]) -> np.ndarray:
        if value is None:
            raise self.error(field, "is missing")
        array = np.asarray(value)
        if array.dtype == object:
            raise self.error(field, "holds Python objects, not numbers")
        wanted = ", ".join(str(size) for size in shape)
        matches = array.ndim == len(shape) and all(
            isinstance(size, str) or size == actual
            for size, actual in zip(shape, array.shape, strict=True)
        )
        if not matches:
            raise self.error(field, f"must have shape ({wanted}), got {array.shape}")
        return array

    def floats(self, field: str, value: Any, shape: tuple[int | str, ...]) -> np.ndarray:
        array = self.shaped(field, value, shape)
        if not (np.issubdtype(array.dtype, np.floating) or np.issubdtype(array.dtype, np.integer)):
            raise self.error(field, f"must hold real numbers, got dtype {array.dtype}")
        array = np.ascontiguousarray(array, dtype=np.float32)
        if not np.isfinite(array).all():
            raise self.error(field, "contains NaN or infinite values (after conversion to float32)")
        return array

    def integers(self, field: str, value: Any, shape: tuple[int | str, ...]) -> np.ndarray:
        array = self.shaped(field, value, shape)
        if not np.issubdtype(array.dtype, np.integer):
            raise self.error(field, f"must hold integers, got dtype {array.dtype}")
        return np.ascontiguousarray(array, dtype=np.int64)

    def indices(
        self, field: str, value: Any, shape: tuple[int | str, ...], count: int
    ) -> np.ndarray:
        array = self.integers(field, value, shape)
        if array.size and (array.min() < 0 or array.max() >= count):
            raise self.error(
                field, f"must index 0..{count - 1}, got values {array.min()}..{array.max()}"
            )
        return array.astype(np.int32)

    def names(self, field: str, value: Any, count: int) -> tuple[str, ...]:
        names = tuple(str(name) for name in np.asarray(value).reshape(-1).tolist())
        if len(names) != count:
            raise self.error(field, f"must hold {count} names, got {len(names)}")
        return names

    def rows_sum_to_one(self, field: str, array: np.ndarray, non_negative: bool) -> None:
        if non_negative and (array < 0).any():
            raise self.error(field, f"must be non-negative, found {array.min():.3g}")
        deviation = np.abs(array.astype(np.float64).sum(axis=1) - 1.0)
        if deviation.size and deviation.max() > WEIGHT_SUM_TOLERANCE:
            worst = int(deviation.argmax())
            total = float(array[worst].astype(np.float64).sum())
            raise self.error(field, f"rows must sum to 1, row {worst} sums to {total:.6g}")


def load_body_asset(path: str | Path, num_betas: int | None = None) -> BodyAsset:
    """Read a body model: hkpd's ``.npz``, or an SMPL ``.pkl``/``.npz`` (converted).

    Args:
        path: the file.
        num_betas: shape coefficients to keep (the first ones). None keeps all of an hkpd file
            and the first 10 of an SMPL file.

    Returns:
        The validated :class:`BodyAsset`.

    Raises:
        FileNotFoundError: ``path`` does not exist.
        ValueError: the file is not a body model, or a field has the wrong shape or values.
        pickle.UnpicklingError: a ``.pkl`` names a class other than numpy's, scipy.sparse's or
            chumpy's.
        ImportError: a ``.pkl`` holds scipy sparse matrices and scipy is not installed.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"body model file not found: {path}")
    suffix = path.suffix.lower()
    if suffix == ".pkl":
        return _smpl_to_asset(_read_smpl_pickle(path), path, num_betas)
    if suffix != ".npz":
        raise ValueError(f"{path}: unknown body model format; expected a .npz or an SMPL .pkl")
    try:
        archive = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as problem:
        raise ValueError(f"{path}: not a readable .npz archive ({problem})") from None
    with archive:
        keys = set(archive.files)
        if "joint_template" in keys:
            return _hkpd_npz_to_asset(archive, path, num_betas)
        if "J_regressor" in keys or "kintree_table" in keys:
            fields = {key: _npz_field(archive, key, path) for key in SMPL_FIELDS if key in keys}
            return _smpl_to_asset(fields, path, num_betas)
    raise ValueError(
        f"{path}: neither an hkpd body asset (no 'joint_template') nor an SMPL model "
        f"(no 'J_regressor'/'kintree_table'); keys found: {sorted(keys)}"
    )


def _npz_field(archive: Any, key: str, path: Path) -> np.ndarray:
    try:
        return archive[key]
    except ValueError:  # an object array, which would need pickle
        raise ValueError(
            f"{path}: field '{key}' is stored as pickled Python objects, which hkpd does not "
            "load; re-save it as a plain numeric array"
        ) from None


def _hkpd_npz_to_asset(archive: Any, path: Path, num_betas: int | None) -> BodyAsset:
    missing = [key for key in REQUIRED_FIELDS if key not in archive.files]
    if missing:
        raise ValueError(
            f"{path}: missing field(s) {missing} of the hkpd body asset format "
            "(docs/body_asset_format.md); rebuild it with `python -m hkpd.body.build_from_anny`"
        )
    known = (*REQUIRED_FIELDS, *OPTIONAL_FIELDS)
    fields = {key: _npz_field(archive, key, path) for key in known if key in archive.files}
    shapedirs, joint_shapedirs = fields["shapedirs"], fields["joint_shapedirs"]
    if num_betas is not None:
        _check_enough_betas(path, "shapedirs", shapedirs, num_betas)
        shapedirs, joint_shapedirs = shapedirs[..., :num_betas], joint_shapedirs[..., :num_betas]
    metadata = fields.get("metadata")
    sex_means, sex_covariances = fields.get("sex_shape_means"), fields.get("sex_shape_covariances")
    if num_betas is not None and sex_means is not None and sex_covariances is not None:
        # A Gaussian's marginal over the first coefficients is its sub-block.
        sex_means = sex_means[:, :num_betas]
        sex_covariances = sex_covariances[:, :num_betas, :num_betas]
    return BodyAsset(
        v_template=fields["v_template"],
        faces=fields["faces"],
        shapedirs=shapedirs,
        joint_template=fields["joint_template"],
        joint_shapedirs=joint_shapedirs,
        skinning_weights=fields["skinning_weights"],
        parents=fields["parents"],
        joint_names=fields["joint_names"],
        part_labels=fields["part_labels"],
        part_names=fields["part_names"],
        keypoint_regressor=fields.get("keypoint_regressor"),
        posedirs=fields.get("posedirs"),
        sex_shape_means=sex_means,
        sex_shape_covariances=sex_covariances,
        metadata="{}" if metadata is None else str(metadata.item()),
        source=str(path),
    )


def _check_enough_betas(path: Path, field: str, shapedirs: Any, num_betas: int) -> None:
    available = np.shape(shapedirs)[-1] if np.ndim(shapedirs) == 3 else 0
    if num_betas < 0 or num_betas > available:
        raise ValueError(
            f"{path}: asked for {num_betas} shape coefficients but field '{field}' has "
            f"{available}; pass num_betas <= {available}"
        )


def save_body_asset(asset: BodyAsset, path: str | Path) -> None:
    """Write ``asset`` to ``path`` as a compressed hkpd ``.npz`` (``docs/body_asset_format.md``).

    The file is written exactly at ``path`` (no suffix is added). Optional fields that are None
    are left out.
    """
    arrays: dict[str, np.ndarray] = {
        "v_template": asset.v_template.astype(np.float32),
        "faces": asset.faces.astype(np.int32),
        "shapedirs": asset.shapedirs.astype(np.float32),
        "joint_template": asset.joint_template.astype(np.float32),
        "joint_shapedirs": asset.joint_shapedirs.astype(np.float32),
        "skinning_weights": asset.skinning_weights.astype(np.float32),
        "parents": asset.parents.astype(np.int32),
        "joint_names": np.asarray(asset.joint_names, dtype=str),
        "part_labels": asset.part_labels.astype(np.uint8),
        "part_names": np.asarray(asset.part_names, dtype=str),
        "metadata": np.asarray(asset.metadata, dtype=str),
    }
    if asset.keypoint_regressor is not None:
        arrays["keypoint_regressor"] = asset.keypoint_regressor.astype(np.float32)
    if asset.posedirs is not None:
        arrays["posedirs"] = asset.posedirs.astype(np.float32)
    if asset.sex_shape_means is not None and asset.sex_shape_covariances is not None:
        arrays["sex_shape_means"] = asset.sex_shape_means.astype(np.float32)
        arrays["sex_shape_covariances"] = asset.sex_shape_covariances.astype(np.float32)
    with open(path, "wb") as file:
        np.savez_compressed(file, **arrays)


# --- SMPL -------------------------------------------------------------------------------------


def _smpl_to_asset(fields: dict[str, Any], path: Path, num_betas: int | None) -> BodyAsset:
    """Convert SMPL's fields (numpy arrays or scipy sparse matrices) to a :class:`BodyAsset`."""
    missing = [key for key in SMPL_FIELDS if key not in fields]
    if missing:
        raise ValueError(f"{path}: SMPL model file lacks field(s) {missing}")
    source = f"{path} (SMPL)"
    check = _FieldChecker(source)
    v_template = check.shaped("v_template", _dense(fields["v_template"], path), ("V", 3))
    v_template = v_template.astype(np.float64)
    vertices = v_template.shape[0]
    shapedirs = check.shaped("shapedirs", _dense(fields["shapedirs"], path), (vertices, 3, "S"))
    kept = DEFAULT_SMPL_BETAS if num_betas is None else num_betas
    _check_enough_betas(path, "shapedirs", shapedirs, kept)
    shapedirs = shapedirs[..., :kept].astype(np.float64)
    regressor = check.shaped(
        "J_regressor", _dense(fields["J_regressor"], path), (NUM_JOINTS, vertices)
    )
    regressor = regressor.astype(np.float64)
    weights = check.shaped("weights", _dense(fields["weights"], path), (vertices, NUM_JOINTS))
    posedirs = _dense(fields["posedirs"], path)
    faces = check.shaped("f", _dense(fields["f"], path), ("F", 3))
    parents = _smpl_parents(check, _dense(fields["kintree_table"], path))
    return BodyAsset(
        v_template=v_template,
        faces=faces.astype(np.int64),
        shapedirs=shapedirs,
        joint_template=regressor @ v_template,
        joint_shapedirs=np.einsum("jv,vck->jck", regressor, shapedirs),
        skinning_weights=weights,
        parents=parents,
        joint_names=SMPL_JOINT_NAMES,
        part_labels=np.asarray(weights).argmax(axis=1),
        part_names=SMPL_JOINT_NAMES,
        keypoint_regressor=None,
        posedirs=posedirs,
        metadata=json.dumps(
            {"source": f"SMPL model file {path.name}", "converted_by": "hkpd", "num_betas": kept}
        ),
        source=source,
    )


def _smpl_parents(check: _FieldChecker, kintree_table: np.ndarray) -> np.ndarray:
    """Parents from SMPL's ``kintree_table`` ``(2, 24)``: row 0 parent ids, row 1 joint ids."""
    table = check.shaped("kintree_table", kintree_table, (2, NUM_JOINTS))
    if not np.issubdtype(table.dtype, np.integer) and not np.array_equal(table, np.round(table)):
        raise check.error("kintree_table", f"must hold integer ids, got dtype {table.dtype}")
    table = table.astype(np.int64)
    index_of = {int(joint_id): index for index, joint_id in enumerate(table[1])}
    if len(index_of) != NUM_JOINTS:
        raise check.error("kintree_table", "row 1 must list 24 distinct joint ids")
    # The root's parent id is not a joint id (SMPL uses 2**32 - 1, some files -1).
    return np.array([index_of.get(int(parent_id), -1) for parent_id in table[0]])


def _dense(value: Any, path: Path) -> np.ndarray:
    """A numpy array from an array, a scipy sparse matrix or a chumpy stand-in."""
    if isinstance(value, _ChumpyArray):
        value = value.array(path)
    if hasattr(value, "toarray") and callable(value.toarray):  # scipy.sparse
        value = value.toarray()
    return np.asarray(value)


class _ChumpyArray:
    """Stand-in for a pickled chumpy object: keeps its state and exposes the array inside."""

    chumpy_class = "chumpy.ch.Ch"

    def __setstate__(self, state: Any) -> None:
        self._state = state

    def array(self, path: Path) -> np.ndarray:
        state = getattr(self, "_state", None)
        if isinstance(state, tuple):  # (dict state, slot state)
            merged: dict[str, Any] = {}
            for part in state:
                if isinstance(part, dict):
                    merged.update(part)
            state = merged
        if not isinstance(state, dict):
            raise ValueError(f"{path}: pickled {self.chumpy_class} object carries no array")
        value = state.get("x")
        if value is None:  # not a plain Ch: accept its only array, if it has exactly one
            arrays = [v for v in state.values() if isinstance(v, np.ndarray | _ChumpyArray)]
            if len(arrays) != 1:
                raise ValueError(
                    f"{path}: cannot find the array inside pickled {self.chumpy_class} object "
                    f"(its fields: {sorted(map(str, state))}); re-save the model with plain "
                    "numpy arrays"
                )
            value = arrays[0]
        if isinstance(value, _ChumpyArray):
            return value.array(path)
        return np.asarray(value)


def _chumpy_stand_in(module: str, name: str) -> type:
    return type(name, (_ChumpyArray,), {"chumpy_class": f"{module}.{name}"})


def _scipy_sparse_class(module: str, name: str, path: Path) -> Callable[..., Any]:
    try:
        import scipy.sparse
    except ImportError:
        raise ImportError(
            f"{path} holds scipy sparse matrices (SMPL's J_regressor); install scipy to read it: "
            "pip install scipy"
        ) from None
    found = getattr(scipy.sparse, name, None)
    sparse_types = (scipy.sparse.spmatrix, scipy.sparse.sparray)
    if not (isinstance(found, type) and issubclass(found, sparse_types)):
        raise pickle.UnpicklingError(
            f"{path}: refusing to load '{module}.{name}' (not a scipy sparse matrix class)"
        )
    return found


def _numpy_globals() -> dict[tuple[str, str], Any]:
    """The pickle globals that rebuild numpy arrays, dtypes and scalars."""
    reconstruct = np.empty(0).__reduce__()[0]
    scalar = np.float64(0.0).__reduce__()[0]
    allowed: dict[tuple[str, str], Any] = {
        ("numpy", "ndarray"): np.ndarray,
        ("numpy", "dtype"): np.dtype,
    }
    for module in ("numpy.core.multiarray", "numpy._core.multiarray"):
        allowed[(module, "_reconstruct")] = reconstruct
        allowed[(module, "scalar")] = scalar
    return allowed


def _plain_globals() -> dict[tuple[str, str], Any]:
    """Harmless builtins that Python 2 and protocol-2 pickles refer to."""
    import codecs
    import copyreg

    allowed: dict[tuple[str, str], Any] = {
        ("copy_reg", "_reconstructor"): copyreg._reconstructor,
        ("copyreg", "_reconstructor"): copyreg._reconstructor,
        ("_codecs", "encode"): codecs.encode,  # how protocol 2 stores bytes
    }
    for module in ("__builtin__", "builtins"):
        for builtin in (object, set, frozenset, complex):
            allowed[(module, builtin.__name__)] = builtin
    return allowed


class _SmplUnpickler(pickle.Unpickler):
    """Unpickler that builds only numpy arrays, scipy sparse matrices and chumpy stand-ins."""

    def __init__(self, file: io.BufferedIOBase, path: Path) -> None:
        super().__init__(file, encoding="latin1")
        self.path = path
        self.allowed = {**_numpy_globals(), **_plain_globals()}

    def find_class(self, module: str, name: str) -> Any:
        if module == "chumpy" or module.startswith("chumpy."):
            return _chumpy_stand_in(module, name)
        if (module, name) in self.allowed:
            return self.allowed[(module, name)]
        if module == "scipy.sparse" or module.startswith("scipy.sparse."):
            return _scipy_sparse_class(module, name, self.path)
        raise pickle.UnpicklingError(
            f"{self.path}: refusing to load '{module}.{name}': an SMPL model file holds only "
            "numpy arrays, scipy sparse matrices and chumpy arrays, so this file is not one "
            "(and loading it could run arbitrary code)"
        )


def _read_smpl_pickle(path: Path) -> dict[str, Any]:
    with open(path, "rb") as file:
        try:
            content = _SmplUnpickler(file, path).load()
        except (EOFError, ValueError, TypeError, AttributeError, IndexError) as problem:
            raise ValueError(f"{path}: not a readable SMPL pickle ({problem})") from None
    if not isinstance(content, dict):
        raise ValueError(
            f"{path}: an SMPL .pkl holds a dict of arrays, this one holds {type(content).__name__}"
        )
    return content
