# Maps over test poses (Figures 6-10). Each map is split into tiles of `maps.tile_cells` symmetry classes,
# one job each, so that `--cores N` or the SLURM profile (workflow/profiles/slurm) runs them in parallel.
# Tiles and maps are handed over as binary .npz files (layout in src/stiffcal/planning/maps.py); map.csv is for users.


wildcard_constraints:
    study="[A-Za-z0-9_.-]+",
    tile="[0-9]+",


rule map_tile:
    output:
        npz=temp(f"{MAPS}/{{study}}/tiles/{{tile}}.npz"),
    params:
        map=lambda wc: map_params(wc.study),
        code=code_version("map_tile"),
    log:
        f"{LOGS}/maps/{{study}}/tile{{tile}}.log",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    conda:
        ENV
    script:
        "../scripts/map_tile.py"


# A map of one tile (the default: 1-degree maps have fewer symmetry classes than `maps.tile_cells`) is computed
# by its map_merge job itself: no tile job, no tile file, one start-up.
rule map_merge:
    input:
        tiles=lambda wc: map_tiles(wc.study),
    output:
        npz=f"{MAPS}/{{study}}/map.npz",
        csv=f"{MAPS}/{{study}}/map.csv",
    params:
        map=lambda wc: map_params(wc.study),
        code=code_version("map_merge"),
    log:
        f"{LOGS}/maps/{{study}}/merge.log",
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/map_merge.py"


rule map_grid_statistics:
    input:
        map=f"{MAPS}/{{study}}/map.npz",
    output:
        npz=f"{MAPS}/{{study}}/grid_statistics.npz",
    params:
        map=lambda wc: {**map_params(wc.study), "statistics_steps_deg": MAP_SETTINGS["statistics_steps_deg"]},
        code=code_version("map_grid_statistics"),
    log:
        f"{LOGS}/maps/{{study}}/grid_statistics.log",
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/map_grid_statistics.py"


rule map_statistics:
    input:
        maps=expand(f"{MAPS}/{{study}}/map.npz", study=MAP_STUDIES),
        grid=[f"{MAPS}/{MAP_FIGURES[7]}/grid_statistics.npz"] if 7 in MAP_FIGURES else [],
        printed=PRINTED,
    output:
        csv=f"{TABLES}/map_statistics.csv",
    params:
        maps={"studies": [map_params(n) for n in MAP_STUDIES],
              "statistics_steps_deg": MAP_SETTINGS["statistics_steps_deg"]},
        code=code_version("map_statistics"),
    log:
        f"{LOGS}/map_statistics.log",
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/map_statistics.py"


rule map_pairs:
    output:
        npz=f"{MAPS}/{{study}}/pairs.npz",
        csv=f"{MAPS}/{{study}}/pairs.csv",
    params:
        # only what changes the pairs (not the single-pose grid step_deg or tile_cells)
        map=lambda wc: {**{k: map_params(wc.study)[k] for k in ("name", "link_ratio", "force_deg")},
                        "pairs_step_deg": MAP_SETTINGS["pairs_step_deg"]},
        code=code_version("map_pairs"),
    log:
        f"{LOGS}/maps/{{study}}/pairs.log",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    conda:
        ENV
    script:
        "../scripts/map_pairs.py"


rule map_figures:
    input:
        **{f"fig{k}": f"{MAPS}/{name}/map.npz" for k, name in MAP_FIGURES.items()},
        pairs=[f"{MAPS}/{MAP_FIGURES[7]}/pairs.npz"] if 7 in MAP_FIGURES else [],
    output:
        **{f"{name}_{ext}": f"{FIGURES}/{name}.{ext}" for name in map_figure_outputs() for ext in ("png", "svg")},
    params:
        figures={k: map_params(name) for k, name in sorted(MAP_FIGURES.items())},
        code=code_version("map_figures"),
    log:
        f"{LOGS}/map_figures.log",
    conda:
        ENV
    script:
        "../scripts/map_figures.py"
