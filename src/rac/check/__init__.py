"""The checker: names, types and the model block resolved into the IR, and the static analyses."""
