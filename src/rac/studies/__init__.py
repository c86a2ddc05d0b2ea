"""The paper's studies: the pre-analysis sweep and the learning experiment."""
