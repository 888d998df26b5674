"""Lot acceptance: ISO 2859-1 single sampling plans and the decision on a lot from its recorded parts."""
