"""Differentiable geometry kernels (torch): rotations, point-to-cuboid distances, occlusion, inliers."""
