"""MAGNA Studio: design worlds and missions in the browser, and watch and command a running mission."""
