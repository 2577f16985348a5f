"""Reproductions of the seed papers, one module per paper (first author and year)."""
