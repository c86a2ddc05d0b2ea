from rac.cli.main import entry

entry()
