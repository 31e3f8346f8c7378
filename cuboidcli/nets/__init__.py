"""The networks a user runs, with their configs: the sampling-weight network (:mod:`.sampler`), the neural
cuboid solver (:mod:`.solver`) and the monocular depth network (:mod:`.depth`), and their one weights
format (:mod:`.checkpoint`). Inference code builds them from here; their training is in
:mod:`cuboidcli.learn`; which weights file to load, in :mod:`cuboidcli.weights`.
"""
