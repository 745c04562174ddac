//! `raytracer bench`: medians of parse, build, primary-ray, shadow-ray and
//! incoherent-ray times (ray by ray; primary and shadow rays also as 4x4 packets;
//! every kind also through the array queries, `Scene::intersect_primitives` and
//! `Scene::occluded_rays`)
//! on one scene, printed as one JSON object for `bench/run.sh`.

use anyhow::Context;
use raytracer::benchmark::{
    RayWorkload, Times, count_occluded, count_occluded_packets, count_occluded_stream, median_time,
    median_times, median_times_with, trace_closest_primitives, trace_closest_primitives_packets,
    trace_closest_primitives_stream,
};
use raytracer::math::{Float, Ray};
use raytracer::{BvhParams, Scene, render};

use super::args::BenchArgs;

/// Measures as `args` say.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    let path = &args.view.scene;
    let file_bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    let (loaded, parse_s) = median_time(args.repeat, || super::load_scene(&args.view));
    let (description, options) = loaded?;
    let options = &options;
    let triangles = description.triangles.len();
    let params = BvhParams::default();
    // The copy of the description each build consumes is made outside the clock: a
    // render builds from the one it read.
    let (scene, build) = median_times_with(
        args.repeat,
        || description.clone(),
        |d| Scene::build(d, &params),
    );
    let workload = RayWorkload::new(&scene, options);
    let (ids, primary) = median_times(args.repeat, || {
        trace_closest_primitives(&scene, &workload.primary)
    });
    anyhow::ensure!(
        ids.iter().filter(|&&id| id != u32::MAX).count() == workload.primary_hits,
        "closest-hit runs disagree on the number of hits"
    );
    let (packet_ids, primary_packet) = median_times(args.repeat, || {
        trace_closest_primitives_packets(&scene, &workload.primary, &workload.primary_packets)
    });
    anyhow::ensure!(
        packet_ids == ids,
        "packets and single rays disagree on the primary rays' hits"
    );
    // The same rays through the array query: the same hits.
    let (stream_ids, primary_stream) = median_times(args.repeat, || {
        trace_closest_primitives_stream(&scene, &workload.primary)
    });
    anyhow::ensure!(
        stream_ids == packet_ids,
        "the array query and packets disagree on the primary rays' hits"
    );
    let (occluded, shadow) = median_times(args.repeat, || count_occluded(&scene, &workload.shadow));
    let (packet_occluded, shadow_packet) = median_times(args.repeat, || {
        count_occluded_packets(&scene, &workload.shadow, &workload.shadow_packets)
    });
    anyhow::ensure!(
        packet_occluded == occluded,
        "packets and single rays disagree on the number of blocked shadow rays"
    );
    // The same rays through the array query: as many blocked.
    let (shadow_rays, shadow_reach): (Vec<Ray>, Vec<Float>) =
        workload.shadow.iter().copied().unzip();
    let (stream_occluded, shadow_stream) = median_times(args.repeat, || {
        count_occluded_stream(&scene, &shadow_rays, &shadow_reach)
    });
    anyhow::ensure!(
        stream_occluded == occluded,
        "the array query and single rays disagree on the number of blocked shadow rays"
    );
    let (incoherent_ids, incoherent) = median_times(args.repeat, || {
        trace_closest_primitives(&scene, &workload.incoherent)
    });
    let incoherent_hits = incoherent_ids.iter().filter(|&&id| id != u32::MAX).count();
    // The same rays through the array query: the same hits.
    let (stream_ids, incoherent_stream) = median_times(args.repeat, || {
        trace_closest_primitives_stream(&scene, &workload.incoherent)
    });
    anyhow::ensure!(
        stream_ids == incoherent_ids,
        "the array query and single rays disagree on the incoherent rays' hits"
    );
    // The bounce rays again as occlusion queries with no limit (as ambient
    // occlusion's rays): one by one and through the array query. A ray is blocked
    // exactly when it hits something.
    let reach = vec![Float::INFINITY; workload.incoherent.len()];
    let pairs: Vec<(Ray, Float)> = workload
        .incoherent
        .iter()
        .map(|&r| (r, Float::INFINITY))
        .collect();
    let (blocked, occlusion) = median_times(args.repeat, || count_occluded(&scene, &pairs));
    let (stream_blocked, occlusion_stream) = median_times(args.repeat, || {
        count_occluded_stream(&scene, &workload.incoherent, &reach)
    });
    anyhow::ensure!(
        blocked == incoherent_hits && stream_blocked == blocked,
        "occlusion queries disagree with closest hits on the incoherent rays"
    );
    let (_, render) = median_times(args.repeat, || render(&scene, options));
    if let Some(path) = &args.dump_rays {
        let triangles: Vec<[u32; 3]> = description.triangles.iter().map(|t| t.positions).collect();
        workload
            .dump(&description.positions, &triangles, path)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    let summary = scene.bvh_summary();
    // Rays per second of wall time, and per second of CPU time (all threads): the
    // second is steadier on a shared machine.
    let rate = |name: &str, n: usize, t: &Times| {
        format!(
            "\"{name}_ms\": {:.2}, \"{name}_cpu_ms\": {:.2}, \"{name}_mrays_per_s\": {:.2}, \"{name}_mrays_per_cpu_s\": {:.2}",
            t.wall * 1e3,
            t.cpu * 1e3,
            n as f64 / t.wall / 1e6,
            n as f64 / t.cpu / 1e6
        )
    };
    let fields = [
        format!("\"file_bytes\": {file_bytes}, \"triangles\": {triangles}"),
        format!(
            "\"parse_ms\": {:.2}, \"parse_mb_per_s\": {:.1}",
            parse_s * 1e3,
            file_bytes as f64 / parse_s / 1e6
        ),
        format!(
            "\"build_ms\": {:.2}, \"build_cpu_ms\": {:.2}, \"bvh_nodes\": {}, \"sah_cost\": {:.2}, \"wide_nodes\": {}, \"wide_sah_cost\": {:.3}, \"packets\": {}",
            build.wall * 1e3,
            build.cpu * 1e3,
            summary.nodes,
            summary.sah_cost,
            summary.wide_nodes,
            summary.wide_sah_cost,
            summary.packets
        ),
        format!(
            "\"primary_rays\": {}, \"primary_hits\": {}, {}, {}, {}",
            workload.primary.len(),
            workload.primary_hits,
            rate("primary", workload.primary.len(), &primary),
            rate("primary_packet", workload.primary.len(), &primary_packet),
            rate("primary_stream", workload.primary.len(), &primary_stream)
        ),
        format!(
            "\"shadow_rays\": {}, \"shadow_occluded\": {}, {}, {}, {}",
            workload.shadow.len(),
            occluded,
            rate("shadow", workload.shadow.len(), &shadow),
            rate("shadow_packet", workload.shadow.len(), &shadow_packet),
            rate("shadow_stream", workload.shadow.len(), &shadow_stream)
        ),
        format!(
            "\"incoherent_rays\": {}, \"incoherent_hits\": {}, {}, {}",
            workload.incoherent.len(),
            incoherent_hits,
            rate("incoherent", workload.incoherent.len(), &incoherent),
            rate(
                "incoherent_stream",
                workload.incoherent.len(),
                &incoherent_stream
            )
        ),
        format!(
            "\"occlusion_rays\": {}, \"occlusion_blocked\": {}, {}, {}",
            pairs.len(),
            blocked,
            rate("occlusion", pairs.len(), &occlusion),
            rate("occlusion_stream", pairs.len(), &occlusion_stream)
        ),
        format!(
            "\"render_ms\": {:.2}, \"render_cpu_ms\": {:.2}",
            render.wall * 1e3,
            render.cpu * 1e3
        ),
    ];
    super::write_stdout(format!("{{{}}}\n", fields.join(", ")).as_bytes())
}
