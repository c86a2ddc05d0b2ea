"""The `.ra` language: the syntax tree, the parser (lark) and the formatter (`rac fmt`)."""
