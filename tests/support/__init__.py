"""What tests share: fake flight controllers, vehicles, SITL ports and scenario files.

Importable as ``support.*`` from every test (tests/conftest.py puts tests/ on sys.path).
"""
