"""The body model: a free SMPL-format model built from Anny, and a fast skinning layer.

- :class:`BodyModel`: betas and joint rotations to posed vertices, joints and COCO keypoints.
- :class:`BodyAsset`, :func:`load_body_asset`, :func:`save_body_asset`: the asset format
  (``docs/body_asset_format.md``), also read from SMPL model files.
- :mod:`hkpd.body.linear_blend_skinning`: the posing math as pure functions.
"""

from hkpd.body.asset import BodyAsset, load_body_asset, save_body_asset
from hkpd.body.body_model import BodyModel, BodyOutput

__all__ = ["BodyAsset", "BodyModel", "BodyOutput", "load_body_asset", "save_body_asset"]
