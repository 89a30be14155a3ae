"""``bondem generate``: a packing and its bonds, written as particles.csv and bonds.csv."""
import time
import tomllib
from pathlib import Path

import click

from ..errors import InputError


@click.command("generate")
@click.option("--shape", type=click.Choice(["sphere", "box", "cylinder", "mesh"]),
              default="sphere", show_default=True, help="Container shape.")
@click.option("--size", type=float, help="Sphere/cylinder diameter or box edge, m.")
@click.option("--height", type=float, help="Cylinder height, m (default: the diameter).")
@click.option("--mesh", "mesh_file", type=click.Path(dir_okay=False),
              help="Closed STL mesh to fill (implies --shape mesh).")
@click.option("--scale", type=float, default=1.0, show_default=True,
              help="Factor from the STL's units to m.")
@click.option("--radius", type=float, help="Particle radius (or mean radius), m.")
@click.option("--distribution", type=click.Choice(["monodisperse", "normal", "lognormal"]),
              default="monodisperse", show_default=True, help="Radius distribution.")
@click.option("--std", type=float, default=0.0, help="Standard deviation of the radius, m.")
@click.option("--min-radius", type=float, help="Smallest radius kept, m.")
@click.option("--max-radius", type=float, help="Largest radius kept, m.")
@click.option("--solids-fraction", type=float, default=0.55, show_default=True)
@click.option("--max-overlap", type=float, default=1e-3, show_default=True,
              help="Largest overlap allowed, relative to the smaller radius.")
@click.option("--max-gap", type=float, help="Bond every pair with a surface gap up to this, m.")
@click.option("--bond-diameter", type=float, help="Bond diameter, m.")
@click.option("--bond-diameter-ratio", type=float,
              help="Bond diameter over the smaller particle's diameter.")
@click.option("--max-bonds", type=int, help="Cap on bonds per particle (closest first).")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--material", default="glass", show_default=True,
              help="Particle material name written to particles.csv.")
@click.option("--bond-material", default="binder", show_default=True,
              help="Bond material name written to bonds.csv.")
@click.option("--from-scene", type=click.Path(dir_okay=False),
              help="Take [particles] generator and [bonds] from a scene file instead.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=".",
              show_default=True, help="Output folder.")
def command(shape, size, height, mesh_file, scale, radius, distribution, std, min_radius,
            max_radius, solids_fraction, max_overlap, max_gap, bond_diameter,
            bond_diameter_ratio, max_bonds, seed, material, bond_material, from_scene,
            out_dir):
    """Generate a packing (and bonds) and write DIR/particles.csv and DIR/bonds.csv."""
    from ..generate import (bonds_from_table, coordination_number, particles_from_generator,
                            solids_fraction as fraction_of, max_overlap as overlap_of,
                            volume_from_table)
    from ..io.csv_files import write_bonds, write_particles

    if from_scene:
        file = from_scene
        try:
            with open(from_scene, "rb") as handle:
                scene = tomllib.load(handle)
        except (OSError, tomllib.TOMLDecodeError) as error:
            raise InputError(f"cannot read the scene: {error}", file=file) from None
        generator = scene.get("particles", {}).get("generator")
        if not isinstance(generator, dict):
            raise InputError("no [particles] generator = {...} table", file=file,
                             key="particles.generator")
        bonds = scene.get("bonds", {})
        bonds = ({k: v for k, v in bonds.items() if k != "file"}
                 if "max_gap" in bonds else None)
    else:
        file = "<command line>"
        generator = {"shape": "mesh" if mesh_file else shape, "seed": seed,
                     "solids_fraction": solids_fraction, "material": material,
                     "max_overlap": max_overlap}
        if mesh_file:
            generator.update(file=str(Path(mesh_file).resolve()), scale=scale)
        elif size is None:
            raise InputError("--size is required (sphere/cylinder diameter, box edge; m)",
                             key="--size")
        else:
            generator["size"] = size
            if height is not None:
                generator["height"] = height
        if radius is None:
            raise InputError("--radius is required (particle radius, m)", key="--radius")
        if distribution == "monodisperse":
            generator["particle_radius"] = radius
        else:
            table = {"type": distribution, "mean": radius, "std": std}
            if min_radius is not None:
                table["min"] = min_radius
            if max_radius is not None:
                table["max"] = max_radius
            generator["size_distribution"] = table
        bonds = None
        if max_gap is not None:
            bonds = {"max_gap": max_gap, "material": bond_material}
            if bond_diameter is not None:
                bonds["diameter"] = bond_diameter
            if bond_diameter_ratio is not None:
                bonds["diameter_ratio"] = bond_diameter_ratio
            if max_bonds is not None:
                bonds["max_per_particle"] = max_bonds
        elif bond_diameter is not None or bond_diameter_ratio is not None:
            raise InputError("bond diameter given without --max-gap", key="--max-gap")

    start = time.perf_counter()
    clump_of = None
    if "clump" in generator:
        # copies of one clump (scene.py's clump generator): the members, with their clump
        from ..scene import _clump_generator
        base = Path(file).parent if file != "<command line>" else Path(".")
        position, radii, names, clumps = _clump_generator(generator, base / "scene.toml")
        clump_of = clumps["clump_of"]
    else:
        position, radii, names = particles_from_generator(generator, file)
    elapsed = time.perf_counter() - start
    volume = volume_from_table(generator, file).volume
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_particles(out / "particles.csv", position, radii, names, clump=clump_of)
    if clump_of is not None:
        count = int(clump_of.max()) + 1
        click.echo(f"clumps: {count} of {radii.size // count} spheres (particles.csv's "
                   "clump column)")
    click.echo(f"particles: {radii.size}  solids fraction: {fraction_of(radii, volume):.4f}  "
               f"max overlap: {max(overlap_of(position, radii), 0.0):.2e} of the radius  "
               f"time: {elapsed:.1f} s")
    if bonds is not None:
        pairs, diameter, bond_names = bonds_from_table(bonds, position, radii, file,
                                                       clump_of=clump_of)
        write_bonds(out / "bonds.csv", pairs, diameter, bond_names)
        click.echo(f"bonds: {len(pairs)}  coordination number: "
                   f"{coordination_number(pairs, radii.size):.3f}")
    click.echo(f"written: {out / 'particles.csv'}"
               + (f", {out / 'bonds.csv'}" if bonds is not None else ""))
