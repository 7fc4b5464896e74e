from senbench.cli.app import app

app()
