// The path partition's material table; see path_partition.h.
#include "integrators/common/path_partition.h"

#include "analysis/scene_probes.h"
#include "scene/scene.h"

namespace cmlt {

PathPartition::PathPartition(const Scene& scene, PathPart part, bool seen_through_easy)
    : m_part(part), m_seen_through_easy(seen_through_easy) {
    if (part == PathPart::all) return;  // every path: no table needed
    m_specular.resize(scene.material_count());
    for (size_t k = 0; k < m_specular.size(); ++k)
        m_specular[k] = material_may_be_specular(scene.material(uint32_t(k))) ? 1 : 0;
}

}  // namespace cmlt
