from rac.cli import entry

entry()
