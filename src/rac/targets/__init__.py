"""Code generators: each turns a checked :class:`rac.ir.Automaton` into text for one target."""
