"""placeholder — being written."""
def integrate(*a, **k): raise NotImplementedError
