"""What ``hkpd-predict`` writes and draws from a posterior.

- :mod:`~hkpd.prediction.exports.writers`: meshes (PLY / GLB / OBJ), the distribution (NPZ) and
  the summary (JSON).
- :mod:`~hkpd.prediction.exports.combined_shape`: the files of a shape combined from several
  photos (``--same-person``).
- :mod:`~hkpd.prediction.exports.overview`: the overview picture; its pieces
  :mod:`~hkpd.prediction.exports.fit_overlay` (the mode drawn over the photo) and
  :mod:`~hkpd.prediction.exports.uncertainty_colours` (the colour scale the explorer shares).
"""
