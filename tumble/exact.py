"""placeholder — being written."""
