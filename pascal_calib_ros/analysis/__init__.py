"""analysis layer (see /work/shared/DESIGN.md)."""
