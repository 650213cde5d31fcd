"""Pure numerics of scm-calib: the SCM wheel simulator, SWT signals and Bayesian inference."""
