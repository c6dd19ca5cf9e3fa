#include "host/web/report_view.hpp"

#include <fstream>

#include "common/error.hpp"
#include "host/recognize/report.hpp"
#include "host/web/api.hpp"
#include "host/web/assets.hpp"

namespace fs::host::web {

void write_report(const std::filesystem::path& dir, const std::string& title, const OrganizedCloud& cloud,
                  const rec::Recognizer& recognizer, const rec::Recognition& r, const Plane* table) {
  std::filesystem::create_directories(dir);
  copy_view_scripts(dir / "js");
  ScanInfo info;
  info.title = title;
  const nlohmann::json detail = scan_detail_json(info, r, recognizer.library(), cloud, table);
  std::vector<std::int32_t> objects;
  recognizer.object_labels(cloud, objects);
  const std::string points = points_blob(cloud, objects, recognizer.segmentation().labels);
  {
    std::ofstream f(dir / "scene-data.js", std::ios::binary);
    // </script> cannot occur: JSON strings escape nothing of it, but this file is loaded by src=, not inline.
    f << "window.FACETSCAN_SCENE = {\"detail\": " << detail.dump() << ",\n\"points\": \""
      << rec::base64(points) << "\"};\n";
    if (!f) throw Error((dir / "scene-data.js").string() + ": cannot write");
  }
  const std::string view =
      "<style>.fs3d{display:flex;gap:1em;flex-wrap:wrap;margin-bottom:1em}#view3d{width:min(900px,100%);"
      "height:560px;border:1px solid #ccc;position:relative}#view3d canvas{display:block}.fs-info{flex:1;"
      "min-width:280px}.fs-info button{margin:2px;padding:3px 8px;cursor:pointer}.sw{display:inline-block;"
      "width:12px;height:12px;margin-right:6px;vertical-align:middle}.kv "
      "th{text-align:left;background:#f4f4f4}"
      ".mono{font-family:monospace}</style>\n"
      "<h2>3D view</h2><p>Drag to orbit, wheel to zoom, right-drag to pan; click an object.</p>\n"
      "<div class=\"fs3d\"><div id=\"view3d\"></div><div class=\"fs-info\" id=\"view3d-info\"></div></div>\n"
      "<script src=\"js/three.min.js\"></script><script src=\"js/OrbitControls.js\"></script>"
      "<script src=\"js/view3d.js\"></script><script src=\"scene-data.js\"></script>\n"
      "<script>FacetView.report(document.getElementById('view3d'), document.getElementById('view3d-info'), "
      "window.FACETSCAN_SCENE);</script>\n";
  rec::write_report(dir, title, cloud, recognizer, r, view);
}

}  // namespace fs::host::web
