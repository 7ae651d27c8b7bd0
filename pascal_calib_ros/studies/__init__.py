"""studies layer (see /work/shared/DESIGN.md)."""
