"""Geometry kernels everything else builds on: rotations, point-to-cuboid distances, occlusion, inliers
(torch, differentiable: :mod:`.kernels`), their numba building blocks for the fused CPU loops
(:mod:`.numba_kernels`), and gravity (:mod:`.gravity`)."""
