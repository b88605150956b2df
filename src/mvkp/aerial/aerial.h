// Aerial photo -> LiDAR depth registration, end to end (issue 8; thesis ch. 7
// stage 1): building regions of the depth image (buildings/), roof regions of
// the photo (ortho/), shape matching and propagation with the image check
// (shapes/). The one pipeline behind `mvkp register` and the Python
// module's register_aerial().
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/aerial/cast_shadows.h"
#include "mvkp/buildings/depth_regions.h"
#include "mvkp/ortho/optical_regions.h"
#include "mvkp/ortho/shadows.h"
#include "mvkp/shapes/edge_evidence.h"
#include "mvkp/shapes/outline_search.h"
#include "mvkp/shapes/register.h"

namespace mvkp {

struct AerialOptions {
  int photo_max_side = 1200;  // larger photos are segmented downscaled to this side (0: never);
                              //   roofs stay tens of pixels wide, memory and time follow the smaller image
  // Coarse photos (issue 21): buildings a few px across, which the
  // segmentation merges with their gardens. A photo smaller than
  // photo_min_side is also segmented upscaled to it (by at most
  // photo_max_upscale, cubic); when the region routes find nothing at the
  // working size, they are tried on those regions. Their answer needs
  // upscaled_min_pairs region pairs and an image check of at least
  // upscaled_min_edge_contrast (docs/aerial.md, "Coarse photos").
  int photo_min_side = 1200;
  double photo_max_upscale = 3;
  int upscaled_min_pairs = 4;
  double upscaled_min_edge_contrast = 1.9;
  bool image_check = true;    // EdgeEvidence (edge_evidence.h) on the photo and all depth outlines
  // Cast shadows (ortho/shadows.h; docs/aerial.md, "Shadow compensation").
  // shadows.enabled: relit before everything else sees the working photo
  // (off by default: as the first pass it loses as many answers as it
  // gains). shadow_fallback: when the photo as it is gives no registration,
  // a second pass on the working photo relit (the depth's regions reused),
  // whose answer is kept only from the region routes (the outline search
  // registered a photo of other ground on a relit photo).
  ShadowOptions shadows;
  bool shadow_fallback = true;
  // Shadows cast by the depth (cast_shadows.h; docs/aerial.md, "Shadows cast
  // by the depth"): when neither pass above registers the photo, the sun is
  // fitted at the outline search's best pose (refused, but where the depth's
  // buildings are likely to be) and the shadows the depth casts there are
  // relit; the region routes then try that photo (the depth's regions
  // reused). Off when cast_shadow_fallback is false or no sun stands out.
  bool cast_shadow_fallback = true;
  int cast_shadow_candidates = 6;     // refused region sets tried as poses, at most (and the outline search's)
  // A candidate the shadows single out, confirmed by the edges (method
  // kAuto only; kRegions answers by region shapes alone): when the
  // region routes do not answer on the relit photo either, the candidate
  // whose sun stands out by at least this margin (CastShadowFit::margin) is
  // refined and relocated on the relit photo's edges and answers when every
  // check of the outline search's answers passes there and it moved at most
  // cast_shadow_confirm_px (0 turns this off).
  double cast_shadow_confirm_margin = 0.3;
  double cast_shadow_confirm_px = 12;  // depth px
  CastShadowOptions cast_shadows;
  DepthSegmentOptions depth;
  OpticalSegmentOptions optical;
  EdgeEvidenceOptions edge;
  RegistrationOptions registration;
  // Which method answers (issue 21). kRegions: region shapes (register.h)
  // only. kOutlines: the outline search (outline_search.h) only. kAuto: the
  // regions first; the outline search when they find no registration.
  enum class Method { kAuto, kRegions, kOutlines } method = Method::kAuto;
  int auto_outline_max_regions = 0;   // kAuto runs the outline search only on depths with at most this
                                      //   many building regions (0: any). Since it works on a small copy
                                      //   of the photo and its answers must be determined to ambiguity_px,
                                      //   it adds right answers on large tiles too (docs/aerial.md)
  // Large tiles: depths with more than large_tile_regions building regions
  // (0: none), where the outline search was not built. Its coarse cost goes
  // as the template's area, so the template is capped at
  // large_tile_template_radius cells (4x faster than 24 on 1000 x 1000
  // tiles); and with tens of outlines in view a right pose puts a clear
  // majority on edges, while poses caught between roofs and ground (a lean
  // the refinement did not reach) put about half: large_tile_min_on_edges.
  int large_tile_regions = 12;
  int large_tile_template_radius = 16;
  double large_tile_min_on_edges = 0.6;
  int outline_max_side = 600;         // the outline search sees the photo downscaled to this side (0: the
                                      //   working photo, photo_max_side): its oriented-edge fields are its
                                      //   memory (~45 MB at 1200 px); the image check that refines and
                                      //   judges its answer keeps the working photo
  OutlineSearchOptions outline;
  // On tiles of at most large_tile_regions buildings the outline search
  // also scores the outlines of what else stands above the ground (trees,
  // hedges, sheds: ObjectOutlines, depth_regions.h; at
  // OutlineSearchOptions::object_weight); they never count as outlines in
  // view nor in the acceptance. A tile of 3-6 buildings shows 2-3 outlines
  // in a photo; a large tile shows tens, and its hundreds of tree crowns
  // drew the search to wrong scales (issue 21, docs/aerial.md). Likewise
  // the search's completeness weight (OutlineSearchOptions::
  // completeness_power) applies to small tiles only: on large tiles it
  // changed no answer but one, a clear winner relocated 9.5 px off, and the
  // relocation's confidence bound was measured on unweighted scores.
  bool outline_objects = true;
  ObjectOutlineOptions objects;
  // The outline search's best pose, refused but a clear winner (its
  // confidence >= this; 0: off), is relocated (EdgeEvidence::Relocate) and
  // becomes its answer when the outlines then lie on edges as the search
  // asks (contrast, min_on_edges); every later check still applies
  // (docs/aerial.md, "A clear winner relocated").
  double outline_relocate_confidence = 0.75;
  // The outline search's answer rests on edges alone (no region shapes), so
  // its roofs must stand apart (roof contrast >= EdgeEvidenceOptions::
  // roof_veto) whenever they are scored over at least this many outlines,
  // however clear its edges (the edges-only exemption, roof_veto_below, is
  // for the region routes); 0: the region routes' rule. On seeds 122-132 the
  // outline answers with roofs below 1.1 over 2 or more outlines were 2 of 2
  // wrong (5.1 and 771.8 px; edges 2.41 and 2.52), the right ones 1.17 and
  // above; over one outline a right answer scored 0.74 and a wrong one 0.72
  // (docs/aerial.md, "The pose the shadows single out").
  int outline_roof_veto_regions = 2;
  // Ground size of a pixel, metres (0: unknown). When both are known the
  // outline search looks only near their ratio of scales.
  double photo_res_m = 0, depth_res_m = 0;
  void Check() const;  // throws Error(kInvalidArgument)
};

struct AerialRegistration {
  Registration registration;          // photo px (full size) -> depth px
  std::vector<Contour> photo_regions;  // in full-size photo px
  std::vector<Contour> depth_regions;  // depth px
  std::vector<double> photo_region_confidence;  // per photo region (ortho's confidence)
  double photo_upscale = 1;            // the photo regions were segmented this many times the working size
  std::string method;                  // which method gave `registration`: "regions" | "single-pair" | "outlines" |
                                       //   "cast-shadows" (AerialOptions::cast_shadow_confirm_margin)
  double confidence = 0;               // [0, 1] of the answer (see docs/aerial.md); 0 when !ok
  bool outline_search_ran = false;
  OutlineSearchResult outline;         // the outline search's own result, when it ran
  double outline_search_ms = 0;
  double segment_depth_ms = 0, segment_photo_ms = 0;
  ShadowCompensation shadows;          // what the shadow compensation found and did (working photo)
  bool shadow_fallback_used = false;   // the answer is the shadow fallback's (AerialOptions::shadow_fallback)
  CastShadowFit cast_shadows;          // the depth's shadows, when that fallback ran (applied: a sun was fitted)
  bool cast_shadow_fallback_used = false;  // the answer is that fallback's (AerialOptions::cast_shadow_fallback)
};

// Confidence of a region-method answer with `pairs` region pairs: the share
// of such answers that were right (within 5 px) on the tuning scenes
// (docs/aerial.md, "Confidence"), in [0.67, 0.97].
double RegionConfidence(int pairs);

// `depth`: heights in metres (NaN = no data). `photo`: 8-bit BGR or grey.
// Both are taken by value: pass them with std::move when the caller does not
// need them any more, and their pixels are freed as soon as the pipeline is
// done with them (the full-size photo once downscaled, the depth once
// segmented, the downscaled photo once its segmentation maps are built).
// "No registration found" is a result (registration.ok false with a reason);
// bad input throws Error.
AerialRegistration RegisterAerial(cv::Mat1f depth, cv::Mat photo, const AerialOptions& options = {});

}  // namespace mvkp
