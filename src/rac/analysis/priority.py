from rac import ir
def check_priorities(a): return []
def check_ranges(a): return []
