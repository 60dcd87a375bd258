"""Fitting a personalized head to a photograph (adi fit)."""
