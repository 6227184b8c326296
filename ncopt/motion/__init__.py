"""The program's motion: the interpreter, modal state, planes, tool orientation, kinematics, times."""
