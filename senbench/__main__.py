from senbench.cli import app

app()
