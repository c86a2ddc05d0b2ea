"""What rac shows: plots, rendered scenarios and progress bars."""
