"""The paper's studies: the pre-analysis sweep and the learning experiment.

May import: rac.compiler, core, lang, ir, check, model, runtime, engine, output, learning, verify.
"""
