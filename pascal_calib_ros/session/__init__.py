"""session layer (see /work/shared/DESIGN.md)."""
