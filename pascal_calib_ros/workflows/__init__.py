"""workflows layer (see /work/shared/DESIGN.md)."""
