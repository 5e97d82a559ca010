"""calibration: priors and synthetic likelihoods for fitting flocking-model parameters to data.

``priors`` holds one-parameter prior distributions and their product (:class:`JointPrior`);
``likelihood`` holds the Gaussian synthetic log-likelihood (Wood 2010; Price et al. 2018) and a
diagonal standardised distance for optimisation.
"""
