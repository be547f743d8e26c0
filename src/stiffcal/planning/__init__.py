"""Choosing measurement poses: the design problem and its single-pose search, M-pose plans (one exchange), the
approximate design and its certificate, the cache shared by every M, the maps."""
