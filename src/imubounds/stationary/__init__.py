"""The stationary pipeline (METHOD.md section 1): static log -> Allan family -> noise terms
-> Gauss-Markov / AR models -> stationary bounds.

* :mod:`.allan` (+ :mod:`._allan_kernels`) -- Allan, modified, Hadamard and total
  deviations with confidence intervals (1.1);
* :mod:`.theory` -- what each estimator expects from each noise term and model (1.2);
* :mod:`.terms` -- IEEE 952 noise terms by robust fit and slope read-off, and the
  terms selected for bounds (never 0: upper bounds where the log does not resolve one);
* :mod:`.contamination` -- spikes in a static log (the robust Allan variance's first step);
* :mod:`.models` -- Gauss-Markov and Burg AR models (1.3);
* :mod:`.bounds` -- per-sample stationary bounds and levels (1.4);
* :mod:`.noise_sim` -- noise simulation from terms or models;
* :mod:`.pipeline` -- the whole static analysis of one log;
* :mod:`.stream` -- the same for logs larger than memory;
* :mod:`.fleet` -- many logs on Dask.
"""
