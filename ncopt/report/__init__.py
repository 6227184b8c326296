"""What a person reads: the HTML report, its plots and the diff view."""
