"""Posteriors: how sure each estimate is (emcee sampling, calibrated noise models, surrogates)."""
