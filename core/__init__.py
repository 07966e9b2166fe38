"""hkpd: probabilistic 3D human shape and pose from one photo.

The package follows the data flow image -> proxy -> network -> distribution -> samples -> meshes
-> view. Implemented so far:

- :mod:`hkpd.distributions`: matrix-Fisher distributions over joint rotations (exact normaliser,
  differentiable rejection sampler), the kinematic-tree distribution and the shape Gaussian.
- :mod:`hkpd.kinematic_tree`: the SMPL 24-joint tree.
"""

__version__ = "0.1.0"
