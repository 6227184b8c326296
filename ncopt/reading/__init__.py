"""Reading a program: grammars and dialects, numbers, expressions, what is refused, the ncopt stamp."""
