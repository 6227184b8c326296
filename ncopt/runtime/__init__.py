"""Runtime services every stage may use: errors, files, the terminal, memory and threads."""
