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
@click.option("--overwrite", is_flag=True,
              help="Replace results in OUT that are not an earlier demo's.")
@click.option("--no-progress", is_flag=True, help="No progress bar.")
def command(out_dir, end_time, overwrite, no_progress):
    """Run the demo: a bonded agglomerate of 369 particles hits a wall at 6 m/s; writes
    results.h5 and ParaView files into OUT and says where they are."""
    from ..io.vtk import export_vtk
    from ..runner import RunFailed, run_scene
    from ..scene import load_scene

    # A second `bondem demo` replaces its own earlier run; a folder holding anything else's
    # results is refused as `bondem run` refuses it.
    from ..errors import InputError
    from ..runner import clear_outputs
    earlier = out_dir / "scene.toml"
    own = (earlier.is_file()
           and earlier.read_bytes() == (demo_folder() / "scene.toml").read_bytes())
    if earlier.exists() and not (own or overwrite):
        raise InputError("holds a scene.toml that is not the demo's; give another --out",
                         file=out_dir, key="--out")
    if out_dir.is_dir():
        clear_outputs(out_dir, overwrite=own or overwrite)
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
        results = run_scene(scene, out_dir, progress=not no_progress)
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
