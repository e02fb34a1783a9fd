"""Monocular vision for error correction (thesis §4.2.3): a calibrated camera and the pose of a
known object from four non-coplanar feature points seen in its image."""
