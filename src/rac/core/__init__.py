"""Shared by every stage: source text and spans, diagnostics and their one renderer.

Nothing here knows the `.ra` language; every other package may use it.

May import: nothing of rac.
"""
