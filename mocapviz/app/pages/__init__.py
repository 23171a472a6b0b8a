"""The dashboard pages, one module each (see mocapviz.app)."""
