"""Geometry kernels everything else builds on: rotations, point-to-cuboid distances, occlusion, inliers
(torch, differentiable: :mod:`.kernels`); their fused numba loops on the CPU: the inlier function of one
point and one box (:mod:`.inlier`), the image cells a hypothesis reaches (:mod:`.cells`), hypothesis
scoring (:mod:`.fused`), the refinement's Adam (:mod:`.adam`) and a room's (:mod:`.room`); which of torch
and numba runs on a device (:mod:`.backends`), and gravity (:mod:`.gravity`)."""
