"""What rac shows: plots, rendered scenarios and progress bars.

May import: core, ir, model.
"""
