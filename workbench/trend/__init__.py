"""Control charts over the store's records: I-MR and u-charts, the Nelson rules, drifts towards tolerance."""
