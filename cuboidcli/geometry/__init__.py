"""Geometry kernels everything else builds on: rotations, point-to-cuboid distances, occlusion, inliers
(torch, differentiable: :mod:`.kernels`), the fused numba loops of the same on the CPU (:mod:`.fused`:
hypothesis scoring, and the box helpers the fused solver shares), which of the two runs on a device
(:mod:`.backends`), and gravity (:mod:`.gravity`)."""
