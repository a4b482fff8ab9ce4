// The file dialog's display-free part (ui/file_dialog.h) against a temporary folder tree:
// listing order and filtering, navigation, and which path confirm gives for Open and Save.

#include "ui/file_dialog.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

namespace penumbra {
namespace {

namespace fs = std::filesystem;

/// root/
///   scenes/  a.json  B.JSON  notes.txt  .hidden.json  zeta/  Alpha/  logs/run.jsonl
///   empty/
struct Tree {
    fs::path root;
    Tree() {
        root = fs::temp_directory_path() /
               ("penumbra_filedialog_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(root);
        for (const char* d : {"scenes/zeta", "scenes/Alpha", "scenes/logs", "empty"})
            fs::create_directories(root / d);
        write("scenes/a.json", "{}");
        write("scenes/B.JSON", "{\"objects\":[]}");
        write("scenes/notes.txt", "n");
        write("scenes/.hidden.json", "{}");
        write("scenes/logs/run.jsonl", "");
    }
    ~Tree() { fs::remove_all(root); }
    void write(const std::string& relative, const std::string& text) const {
        std::ofstream(root / relative) << text;
    }
    std::string path(const std::string& relative) const { return (root / relative).string(); }
};

std::vector<std::string> names(const std::vector<FileEntry>& entries) {
    std::vector<std::string> out;
    for (const FileEntry& e : entries) out.push_back(e.name + (e.directory ? "/" : ""));
    return out;
}

TEST(FileDialog, ExtensionsMatchWithoutCase) {
    EXPECT_TRUE(matchesExtension("a.JSON", {".json"}));
    EXPECT_TRUE(matchesExtension("x.glb", {".gltf", ".glb"}));
    EXPECT_FALSE(matchesExtension("a.json.bak", {".json"}));
    EXPECT_FALSE(matchesExtension("json", {".json"}));
    EXPECT_TRUE(matchesExtension("anything", {}));
}

TEST(FileDialog, ListsFoldersFirstThenMatchingFilesSortedWithoutCase) {
    Tree tree;
    const auto entries = listFolder(tree.path("scenes"), {".json"});
    EXPECT_EQ(names(entries),
              (std::vector<std::string>{"Alpha/", "logs/", "zeta/", "a.json", "B.JSON"}));
    EXPECT_EQ(entries[3].size, 2u);
    EXPECT_EQ(entries[4].size, 14u);
    EXPECT_EQ(entries[0].size, 0u);
    // Hidden files on request; no filter lists every file.
    EXPECT_EQ(
        names(listFolder(tree.path("scenes"), {".json"}, true)),
        (std::vector<std::string>{"Alpha/", "logs/", "zeta/", ".hidden.json", "a.json", "B.JSON"}));
    EXPECT_EQ(names(listFolder(tree.path("scenes"), {})).size(), 6u);
    EXPECT_TRUE(listFolder(tree.path("empty"), {".json"}).empty());
    EXPECT_THROW(listFolder(tree.path("missing"), {}), fs::filesystem_error);
}

TEST(FileDialog, NavigatesIntoAndUpFolders) {
    Tree tree;
    FileBrowser b(FileDialogKind::Open, tree.path("scenes/a.json"), {".jsonl"});
    EXPECT_EQ(fs::path(b.folder()), fs::path(tree.path("scenes"))) << b.toString();
    EXPECT_EQ(b.name, "a.json");
    EXPECT_EQ(names(b.entries()), (std::vector<std::string>{"Alpha/", "logs/", "zeta/"}));
    // Into a folder by clicking it; the name field is kept.
    ASSERT_TRUE(b.activate(b.entries()[1])) << b.toString();
    EXPECT_EQ(fs::path(b.folder()), fs::path(tree.path("scenes/logs")));
    EXPECT_EQ(names(b.entries()), (std::vector<std::string>{"run.jsonl"}));
    // Clicking a file fills the name.
    EXPECT_FALSE(b.activate(b.entries()[0]));
    EXPECT_EQ(b.name, "run.jsonl");
    // Up twice reaches the root of the tree; a missing folder changes nothing.
    ASSERT_TRUE(b.up());
    ASSERT_TRUE(b.up());
    EXPECT_EQ(fs::path(b.folder()), tree.root);
    EXPECT_FALSE(b.navigate("nowhere"));
    EXPECT_EQ(fs::path(b.folder()), tree.root);
    EXPECT_TRUE(b.navigate("scenes/../empty/"));
    EXPECT_EQ(fs::path(b.folder()), fs::path(tree.path("empty")));
    EXPECT_TRUE(b.entries().empty());
    // Absolute folders too; at the file-system root, up is refused.
    EXPECT_TRUE(b.navigate("/"));
    EXPECT_FALSE(b.up());
    // A folder as the initial path opens it with an empty name.
    FileBrowser f(FileDialogKind::Open, tree.path("scenes/zeta"), {});
    EXPECT_EQ(fs::path(f.folder()), fs::path(tree.path("scenes/zeta")));
    EXPECT_EQ(f.name, "");
}

TEST(FileDialog, OpenConfirmsOnlyExistingFiles) {
    Tree tree;
    FileBrowser b(FileDialogKind::Open, tree.path("scenes/a.json"), {".json"});
    std::string why;
    auto p = b.confirm(&why);
    ASSERT_TRUE(p.has_value()) << why;
    EXPECT_TRUE(fs::equivalent(*p, tree.path("scenes/a.json")));
    b.name = "missing.json";
    EXPECT_FALSE(b.confirm(&why).has_value());
    EXPECT_NE(why.find("does not exist"), std::string::npos) << why;
    b.name = "";
    EXPECT_FALSE(b.confirm(&why).has_value());
    EXPECT_EQ(why, "no file name");
    // A relative path through sub-folders, and an absolute one.
    b.name = "logs/run.jsonl";
    ASSERT_TRUE(b.confirm(&why).has_value()) << why;
    b.name = tree.path("scenes/B.JSON");
    p = b.confirm(&why);
    ASSERT_TRUE(p.has_value()) << why;
    EXPECT_EQ(*p, tree.path("scenes/B.JSON"));
    // Confirming a folder's name enters it instead of returning it.
    b.name = "zeta";
    EXPECT_FALSE(b.confirm(&why).has_value());
    EXPECT_EQ(fs::path(b.folder()), fs::path(tree.path("scenes/zeta")));
    EXPECT_EQ(b.name, "");
    EXPECT_EQ(why, "");
}

TEST(FileDialog, SaveAppendsTheDefaultExtensionAndNeedsTheFolder) {
    Tree tree;
    FileBrowser b(FileDialogKind::Save, tree.path("scenes/"), {".json"}, ".json");
    std::string why;
    b.name = "new-scene";
    auto p = b.confirm(&why);
    ASSERT_TRUE(p.has_value()) << why;
    EXPECT_EQ(*p, tree.path("scenes/new-scene.json"));
    EXPECT_FALSE(fs::exists(*p));  // the dialog writes nothing
    b.name = "Kept.JSON";
    EXPECT_EQ(*b.confirm(&why), tree.path("scenes/Kept.JSON"));
    b.name = "a.json";  // existing files may be overwritten
    EXPECT_EQ(*b.confirm(&why), tree.path("scenes/a.json"));
    b.name = "nofolder/x.json";
    EXPECT_FALSE(b.confirm(&why).has_value());
    EXPECT_NE(why.find("no folder"), std::string::npos) << why;
    // Several extensions (export): any of them is kept; none gets the default.
    FileBrowser e(FileDialogKind::Save, tree.path("empty"), {".gltf", ".ply", ".png"}, ".gltf");
    e.name = "view.png";
    EXPECT_EQ(*e.confirm(&why), tree.path("empty/view.png"));
    e.name = "lit";
    EXPECT_EQ(*e.confirm(&why), tree.path("empty/lit.gltf"));
}

TEST(FileDialog, RefreshSeesNewFilesAndHiddenOnRequest) {
    Tree tree;
    FileBrowser b(FileDialogKind::Open, tree.path("empty"), {".json"});
    EXPECT_TRUE(b.entries().empty());
    tree.write("empty/late.json", "{}");
    tree.write("empty/.dot.json", "{}");
    b.refresh();
    EXPECT_EQ(names(b.entries()), (std::vector<std::string>{"late.json"}));
    b.showHidden = true;
    b.refresh();
    EXPECT_EQ(names(b.entries()), (std::vector<std::string>{".dot.json", "late.json"}));
    EXPECT_EQ(b.error(), "");
    // A folder that disappears: an error, no entries.
    fs::remove_all(tree.path("empty"));
    b.refresh();
    EXPECT_TRUE(b.entries().empty());
    EXPECT_NE(b.error(), "");
}

}  // namespace
}  // namespace penumbra
