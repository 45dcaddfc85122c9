"""The physical mechanisms, one module each, as pure functions of arrays: ``pairs`` (the
gather/sum primitive), ``kernels``, ``eos``, ``sph``, ``boundary``, ``dem``, ``bonds``,
``fsi``, ``fpi``. Each imports only :mod:`fpsi_jax.model` and ``pairs``; the solver's
stages compose them."""
