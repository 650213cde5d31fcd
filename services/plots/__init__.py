"""Figures (matplotlib, Agg backend): SWT signals, posteriors, sensitivity."""
