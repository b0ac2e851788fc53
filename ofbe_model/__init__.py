"""Estimators (one interface), OFBENet, training, evaluation, statistics and figures.

Empty until the estimator issues land; see README.md for the plan.
"""
