"""analysis.calibration: fitting a flocking model's free parameters to observed flock statistics.

Configuration (``config``: calibration files on the one schema engine, typed settings per method),
priors and synthetic likelihoods (``priors``, ``likelihood``), the theta -> summaries simulator
(``simulator``), the one emcee driver (``mcmc``) and the methods on it: BSL (``bsl``), the emulator
(``training``, ``surrogates``, ``emulated``), optimisation (``optimize``); ``flocksweep calibrate``
(``run``), diagnostics and figures (``diagnostics``, ``plots``), simulation-based calibration (``sbc``,
``sbc_report``), synthetic targets (``synthetic``) and targets from measured tracks with the
``[observation]`` block's checks (``tracks_targets``). This layer sits above ``sweeps`` (its executor,
seed registry and output folders) and ``analysis.reports`` (figure plumbing); see docs/architecture.md.
"""
