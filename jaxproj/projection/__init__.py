"""The projection engine: human descriptors -> robot poses by sparsely sampled correspondence.

One module per stage: ``config`` (settings), ``meanshift`` and ``landmarks`` (landmark pairs),
``elm`` (the kernel banks), ``search`` (exact k-NN), ``projector`` (the pytrees), ``relaxed`` and
``full`` (the two objectives), ``confidence`` (a per-frame confidence from the objective's
value), ``stacked`` (kinematic chains), ``build``, ``model_file`` (save /
load), ``api`` (project, batching, devices; re-exports the public names), ``distributed``
(several hosts); ``ops`` holds the Pallas kernels and the one backend switch ``ops.Impl``.
"""
