"""analysis: flock metrics, figures and reports."""
