// Checks the shape of the code that docs/DESIGN.md promises: pm/ and blocks/ never include a
// GL or window header; files of one concept each (no source file over 800 lines); no include
// cycle between concepts (a header and its .cpp are one concept); and the design map names
// every public header.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

/// Every C++ source and header below the given top-level folders.
std::vector<fs::path> sources(std::initializer_list<const char*> folders) {
  std::vector<fs::path> out;
  for (const char* folder : folders) {
    const fs::path root = fs::path(TERRALOD_SOURCE_DIR) / folder;
    if (!fs::is_directory(root)) continue;
    for (const auto& entry : fs::recursive_directory_iterator(root)) {
      const std::string ext = entry.path().extension().string();
      if (entry.is_regular_file() && (ext == ".cpp" || ext == ".hpp" || ext == ".h"))
        out.push_back(entry.path());
    }
  }
  return out;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// The concept a file belongs to: its path relative to the source root without the extension,
/// with a library's include/terralod/<lib>/ and src/ folders folded onto the library's folder.
std::string concept_of(const fs::path& file) {
  std::string s = fs::relative(file, TERRALOD_SOURCE_DIR).replace_extension().generic_string();
  for (const std::string lib : {"pm", "blocks", "render"}) {
    const std::string inc = lib + "/include/terralod/" + lib + "/", src = lib + "/src/";
    if (s.rfind(inc, 0) == 0) s = lib + "/" + s.substr(inc.size());
    if (s.rfind(src, 0) == 0) s = lib + "/" + s.substr(src.size());
  }
  return s;
}

}  // namespace

TEST(Layering, CoreNeverIncludesGraphicsHeaders) {
  const std::regex gl(R"(#\s*include\s*[<"](GL/|GLES|EGL/|GLFW/|glad/|epoxy/|OSMesa|GL\.h))");
  int files = 0;
  for (const char* folder : {"pm", "blocks"}) {
    const fs::path root = fs::path(TERRALOD_SOURCE_DIR) / folder;
    ASSERT_TRUE(fs::is_directory(root)) << root;
    for (const auto& entry : fs::recursive_directory_iterator(root)) {
      if (!entry.is_regular_file()) continue;
      const std::string ext = entry.path().extension().string();
      if (ext != ".cpp" && ext != ".hpp" && ext != ".h") continue;
      ++files;
      std::ifstream in(entry.path());
      std::string line;
      for (int n = 1; std::getline(in, line); ++n)
        EXPECT_FALSE(std::regex_search(line, gl)) << entry.path().string() << ":" << n << ": " << line;
    }
  }
  EXPECT_GT(files, 5) << "the scan found too few sources; is TERRALOD_SOURCE_DIR right?";
}

TEST(Layering, NoSourceFileOfTheProductPassesEightHundredLines) {
  const auto files = sources({"pm", "blocks", "render", "apps", "bench"});
  ASSERT_GT(files.size(), 20u) << "the scan found too few sources; is TERRALOD_SOURCE_DIR right?";
  for (const fs::path& f : files) {
    std::ifstream in(f);
    std::size_t lines = 0;
    for (std::string line; std::getline(in, line);) ++lines;
    EXPECT_LE(lines, 800u) << f.string() << ": split it along its concepts (docs/DESIGN.md)";
  }
}

TEST(Layering, NoIncludeCycleBetweenConcepts) {
  const auto files = sources({"pm", "blocks", "render", "apps", "bench"});
  std::map<std::string, std::set<std::string>> edges;
  const std::regex include(R"re(#\s*include\s*"([^"]+)")re");
  for (const fs::path& f : files) {
    const std::string from = concept_of(f), text = slurp(f);
    for (std::sregex_iterator it(text.begin(), text.end(), include), end; it != end; ++it) {
      const fs::path target = fs::path((*it)[1].str());
      // A quoted include names a file beside the includer or below a library's include/.
      const fs::path beside = f.parent_path() / target;
      std::string to;
      if (fs::exists(beside)) {
        to = concept_of(fs::canonical(beside));
      } else {
        for (const std::string lib : {"pm", "blocks", "render"}) {
          const fs::path p = fs::path(TERRALOD_SOURCE_DIR) / lib / "include" / target;
          if (fs::exists(p)) to = concept_of(p);
        }
      }
      if (!to.empty() && to != from) edges[from].insert(to);
    }
  }
  ASSERT_FALSE(edges.empty());
  // A private helper (a file in a library's src/ whose concept has no public header) belongs to
  // the concepts that use it: it may include their headers (for their types). The concepts that
  // must not form a cycle are the others; their edges are followed through private helpers.
  std::set<std::string> public_concepts;
  for (const fs::path& f : files)
    if (f.generic_string().find("/src/") == std::string::npos ||
        fs::exists(fs::path(TERRALOD_SOURCE_DIR) / concept_of(f).substr(0, concept_of(f).find('/')) /
                   "include/terralod" / (concept_of(f) + ".hpp")))
      public_concepts.insert(concept_of(f));
  std::map<std::string, std::set<std::string>> uses;  // public concept -> public concepts it uses
  for (const std::string& from : public_concepts) {
    std::set<std::string> seen{from};
    std::vector<std::string> todo(edges[from].begin(), edges[from].end());
    while (!todo.empty()) {
      const std::string v = todo.back();
      todo.pop_back();
      if (!seen.insert(v).second) continue;
      if (public_concepts.count(v)) {
        uses[from].insert(v);
      } else {
        todo.insert(todo.end(), edges[v].begin(), edges[v].end());
      }
    }
  }
  // Depth-first search for a back edge; the path to it is printed.
  std::map<std::string, int> state;  // 0 unseen, 1 on the stack, 2 done
  std::vector<std::string> stack;
  std::function<void(const std::string&)> visit = [&](const std::string& v) {
    state[v] = 1;
    stack.push_back(v);
    for (const std::string& w : uses[v]) {
      if (state[w] == 1) {
        std::string cycle;
        for (auto it = std::find(stack.begin(), stack.end(), w); it != stack.end(); ++it)
          cycle += *it + " -> ";
        ADD_FAILURE() << "include cycle: " << cycle << w;
      } else if (state[w] == 0) {
        visit(w);
      }
    }
    stack.pop_back();
    state[v] = 2;
  };
  for (const std::string& v : public_concepts)
    if (state[v] == 0) visit(v);
  EXPECT_GT(uses.size(), 20u);
}

TEST(Layering, DesignMapNamesEveryPublicHeader) {
  const std::string map = slurp(fs::path(TERRALOD_SOURCE_DIR) / "docs" / "DESIGN.md");
  ASSERT_FALSE(map.empty()) << "docs/DESIGN.md is missing";
  int headers = 0;
  for (const fs::path& f : sources({"pm/include", "blocks/include", "render/include"})) {
    ++headers;
    EXPECT_NE(map.find(f.filename().string()), std::string::npos)
        << f.string() << " is not named in docs/DESIGN.md's map of where each concept lives";
  }
  EXPECT_GT(headers, 20);
}
