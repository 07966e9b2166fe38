"""2D keypoints of people in a photo: BlazePose's two models run on LiteRT.

- :mod:`~hkpd.prediction.detection.keypoint_detector`: :class:`KeypointDetector`, the detector
  hkpd uses (one person, optionally inside a box; every person for the explorer's menu).
- :mod:`~hkpd.prediction.detection.blazepose`: the two-stage pipeline (person detector, then
  landmarks on the region of interest), with :mod:`~hkpd.prediction.detection.anchors`,
  :mod:`~hkpd.prediction.detection.decoding` and :mod:`~hkpd.prediction.detection.warp`.
- :mod:`~hkpd.prediction.detection.models`: the shipped ``.tflite`` files.
- :mod:`~hkpd.prediction.detection.boxes`: the boxes searched for people.
- :mod:`~hkpd.prediction.detection.person_detector`: NanoDet's whole-person boxes (run by
  :mod:`hkpd.model_runtime`), and :mod:`~hkpd.prediction.detection.person_merge`: which box
  each detection is, so that the Person menu lists nobody twice.
- :mod:`~hkpd.prediction.detection.landmark_spread`: how far the keypoints move on a second
  look (a quality signal).
- :mod:`~hkpd.prediction.detection.mediapipe_reference`: the legacy mediapipe pipeline, only as
  the parity reference (the ``[parity]`` extra).
"""
