"""The `.ra` language as text: syntax tree (:mod:`rac.lang.ast`, frozen nodes with spans), the
lark parser with its start rules (a module, an expression, a query list), and the formatter
(``rac fmt``, :mod:`rac.lang.format`).

May import: core.
"""
