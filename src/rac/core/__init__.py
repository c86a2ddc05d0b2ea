"""Shared by every stage: source locations, diagnostics, numbers and the expression printer base."""
