"""Writing the plan into the program: the edits, the targets, the checks of the output, the summary."""
