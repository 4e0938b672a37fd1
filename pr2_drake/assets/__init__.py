"""Asset generation and mesh/model writers (OBJ + MTL, SDFormat)."""
