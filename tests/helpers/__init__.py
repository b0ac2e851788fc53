"""Helpers the tests share: other tools' readers replicated, paths, small builders."""
