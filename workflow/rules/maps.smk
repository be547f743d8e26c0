# Maps over test poses (Figures 6-10). Each map is split into tiles of `maps.tile_cells` symmetry classes,
# one job each, so that `--cores N` or the SLURM profile (workflow/profiles/slurm) runs them in parallel.
# Tiles and maps are handed over as binary .npz files (layout in src/stiffcal/maps.py); map.csv is for users.


wildcard_constraints:
    study="[A-Za-z0-9_.-]+",
    tile="[0-9]+",
    mapfig="7|8|9|10",


rule map_tile:
    output:
        npz=temp(f"{MAPS}/{{study}}/tiles/{{tile}}.npz"),
    log:
        f"{LOGS}/maps/{{study}}/tile{{tile}}.log",
    benchmark:
        f"benchmarks/out/maps/{{study}}/tile{{tile}}.tsv",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    conda:
        ENV
    script:
        "../scripts/map_tile.py"


rule map_merge:
    input:
        tiles=lambda wc: expand(f"{MAPS}/{wc.study}/tiles/{{tile}}.npz", tile=range(MAP_STUDIES[wc.study].n_tiles)),
    output:
        npz=f"{MAPS}/{{study}}/map.npz",
        csv=f"{MAPS}/{{study}}/map.csv",
    log:
        f"{LOGS}/maps/{{study}}/merge.log",
    benchmark:
        f"benchmarks/out/maps/{{study}}/merge.tsv",
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/map_merge.py"


rule map_statistics:
    input:
        maps=expand(f"{MAPS}/{{study}}/map.npz", study=MAP_STUDIES),
        printed=PRINTED,
    output:
        csv=f"{TABLES}/map_statistics.csv",
    log:
        f"{LOGS}/map_statistics.log",
    benchmark:
        "benchmarks/out/map_statistics.tsv"
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/map_statistics.py"


rule fig6:
    input:
        map=lambda wc: f"{MAPS}/{MAP_FIGURES[7]}/map.npz",
    output:
        png=f"{FIGURES}/fig6.png",
        svg=f"{FIGURES}/fig6.svg",
    log:
        f"{LOGS}/fig6.log",
    benchmark:
        f"benchmarks/out/fig6.tsv",
    conda:
        ENV
    script:
        "../scripts/fig6.py"


rule fig_map_poses:
    input:
        map=lambda wc: f"{MAPS}/{MAP_FIGURES[int(wc.mapfig)]}/map.npz",
    output:
        png=f"{FIGURES}/fig{{mapfig}}.png",
        svg=f"{FIGURES}/fig{{mapfig}}.svg",
    log:
        f"{LOGS}/fig{{mapfig}}.log",
    benchmark:
        f"benchmarks/out/fig{{mapfig}}.tsv",
    conda:
        ENV
    script:
        "../scripts/fig_map_poses.py"


rule map_pairs:
    output:
        npz=f"{MAPS}/{{study}}/pairs.npz",
        csv=f"{MAPS}/{{study}}/pairs.csv",
    log:
        f"{LOGS}/maps/{{study}}/pairs.log",
    benchmark:
        f"benchmarks/out/maps/{{study}}/pairs.tsv",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    conda:
        ENV
    script:
        "../scripts/map_pairs.py"


rule fig_map_pairs:
    input:
        pairs=lambda wc: f"{MAPS}/{MAP_FIGURES[7]}/pairs.npz",
    output:
        png=f"{FIGURES}/fig_map_pairs.png",
        svg=f"{FIGURES}/fig_map_pairs.svg",
    log:
        f"{LOGS}/fig_map_pairs.log",
    benchmark:
        "benchmarks/out/fig_map_pairs.tsv"
    conda:
        ENV
    script:
        "../scripts/fig_map_pairs.py"
