"""Balance on a body: servo compliance compensation (:mod:`wbc.balance.compliance`)."""
