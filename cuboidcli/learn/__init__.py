"""Training of the learned components (paper Sec. 3.2.3 and 3.4), and only training: the sampling-weight
network (:mod:`.sampler_train`, :mod:`.seed_train`), the neural solver's synthetic pre-training
(:mod:`.solver_train`), the depth network (:mod:`.depth_train`), end-to-end fine-tuning (:mod:`.finetune`),
their losses, data and multi-process runs. Every trainer is a job of the one training loop
(:mod:`.trainer`). The networks themselves are in :mod:`cuboidcli.nets`; inference never imports this
package."""
