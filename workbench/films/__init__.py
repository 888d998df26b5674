"""Several films on one part: disc-shaped regions of the surface, chosen by hand or split automatically.

``regions`` (discs of faces), ``fit`` (one film's map and what of it stays within the material),
``split`` (``films = "auto"``), ``joins`` (films taken together again) and ``sheet`` (seams, and
the prints' places on one sheet).
"""
