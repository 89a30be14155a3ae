"""``bondem demo``: the built-in scene (an agglomerate hitting a wall), end to end."""
import shutil
import sys
import time
from importlib import resources
from pathlib import Path

import click


def demo_folder() -> Path:
    """The packaged demo scene folder (scene.toml, particles.csv, bonds.csv)."""
    return Path(str(resources.files("bondem") / "data" / "demo"))


@click.command(name="demo")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              default=Path("bondem-demo"), show_default=True, help="Output folder.")
@click.option("--end-time", type=click.FloatRange(min=0.0, min_open=True),
              help="End time (s) instead of the demo's 1 ms.")
@click.option("--no-progress", is_flag=True, help="No progress bar.")
def command(out_dir, end_time, no_progress):
    """Run the demo: a bonded agglomerate of 369 particles hits a wall at 6 m/s; writes
    results.h5 and ParaView files into OUT and says where they are."""
    from ..io.vtk import export_vtk
    from ..runner import RunFailed, run_scene
    from ..scene import load_scene

    out_dir.mkdir(parents=True, exist_ok=True)
    for name in ("scene.toml", "particles.csv", "bonds.csv"):
        shutil.copyfile(demo_folder() / name, out_dir / name)
    overrides = {"simulation.end_time": end_time} if end_time else None
    scene = load_scene(out_dir / "scene.toml", overrides)
    click.echo(f"demo: {scene.model.n_particles} particles, {scene.model.n_bonds} bonds, "
               f"{len(scene.simulation_options.get('walls', []))} wall, "
               f"{scene.end_time * 1e3:g} ms")
    start = time.perf_counter()
    try:
        # the demo's folder is the demo's own: a second `bondem demo` replaces it
        results = run_scene(scene, out_dir, progress=not no_progress, overwrite=True)
    except RunFailed as error:
        click.echo(f"bondem: run failed: {error}", err=True)
        sys.exit(1)
    elapsed = time.perf_counter() - start
    pvd = export_vtk(results, out_dir / "vtk")
    import h5py
    with h5py.File(results, "r") as f:
        active = f["bonds/active"][-1]
        frames = f["time"].shape[0]
    click.echo(f"done in {elapsed:.1f} s wall time: {frames} frames, "
               f"{int((~active).sum())} of {active.size} bonds broken")
    click.echo(f"results:  {results}")
    click.echo(f"ParaView: {pvd}  (open it, glyph particles by 'radius')")
    click.echo("next:")
    click.echo(f"  bondem analyze {results}    # fragments, broken bonds, energy balance")
    click.echo(f"  bondem report {results}     # one HTML page with the figures")
    click.echo(f"  bondem run {out_dir / 'scene.toml'} --out my-run --set "
               "'particles.velocity=[0,0,-3]'   # your own variant")
