// Index: listing a folder · FileBrowser · drawing

#include "ui/file_dialog.h"

#include <imgui.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <system_error>

namespace penumbra {

namespace fs = std::filesystem;

namespace {

std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return s;
}

/// `p` made absolute against `base` and normalised, without a trailing separator.
fs::path absoluteIn(const fs::path& base, const std::string& p) {
    fs::path out = fs::path(p).is_absolute() ? fs::path(p) : base / p;
    out = out.lexically_normal();
    if (out.has_filename() || out == out.root_path()) return out;
    return out.parent_path();  // "a/b/" → "a/b"
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Listing a folder.

std::string FileEntry::toString() const {
    return "FileEntry{" + name + (directory ? "/" : "") + ", " + std::to_string(size) + " B}";
}

bool matchesExtension(const std::string& name, const std::vector<std::string>& extensions) {
    if (extensions.empty()) return true;
    const std::string ext = lower(fs::path(name).extension().string());
    if (ext.empty()) return false;
    for (const std::string& e : extensions)
        if (lower(e) == ext) return true;
    return false;
}

std::vector<FileEntry> listFolder(const std::string& folder,
                                  const std::vector<std::string>& extensions, bool showHidden) {
    std::vector<FileEntry> folders, files;
    for (const fs::directory_entry& d : fs::directory_iterator(folder)) {
        const std::string name = d.path().filename().string();
        if (!showHidden && !name.empty() && name[0] == '.') continue;
        std::error_code ec;
        if (d.is_directory(ec)) {
            folders.push_back(FileEntry{name, true, 0});
        } else if (!ec && matchesExtension(name, extensions)) {
            const std::uintmax_t size = d.file_size(ec);
            files.push_back(FileEntry{name, false, ec ? 0 : size});
        }
    }
    auto byName = [](const FileEntry& a, const FileEntry& b) {
        const std::string la = lower(a.name), lb = lower(b.name);
        return la != lb ? la < lb : a.name < b.name;
    };
    std::sort(folders.begin(), folders.end(), byName);
    std::sort(files.begin(), files.end(), byName);
    folders.insert(folders.end(), files.begin(), files.end());
    return folders;
}

// ---------------------------------------------------------------------------------------------
// FileBrowser.

FileBrowser::FileBrowser(FileDialogKind kind, const std::string& initialPath,
                         std::vector<std::string> extensions, std::string defaultExtension)
    : mKind(kind),
      mExtensions(std::move(extensions)),
      mDefaultExtension(std::move(defaultExtension)) {
    const fs::path cwd = fs::current_path();
    std::error_code ec;
    fs::path start = cwd;
    if (!initialPath.empty()) {
        const fs::path p = absoluteIn(cwd, initialPath);
        if (fs::is_directory(p, ec)) {
            start = p;
        } else {
            if (fs::is_directory(p.parent_path(), ec)) start = p.parent_path();
            name = p.filename().string();
        }
    }
    mFolder = start.string();
    refresh();
}

void FileBrowser::refresh() {
    try {
        mEntries = listFolder(mFolder, mExtensions, showHidden);
        mError.clear();
    } catch (const fs::filesystem_error& e) {
        mEntries.clear();
        mError = e.what();
    }
}

bool FileBrowser::navigate(const std::string& folder) {
    const fs::path p = absoluteIn(mFolder, folder);
    std::error_code ec;
    if (!fs::is_directory(p, ec)) return false;
    try {
        std::vector<FileEntry> entries = listFolder(p.string(), mExtensions, showHidden);
        mFolder = p.string();
        mEntries = std::move(entries);
        mError.clear();
        return true;
    } catch (const fs::filesystem_error&) {
        return false;
    }
}

bool FileBrowser::up() {
    const fs::path p(mFolder);
    if (p == p.root_path() || !p.has_parent_path()) return false;
    return navigate(p.parent_path().string());
}

bool FileBrowser::activate(const FileEntry& entry) {
    if (entry.directory) return navigate(entry.name);
    name = entry.name;
    return false;
}

std::optional<std::string> FileBrowser::resolve(std::string* why) const {
    auto fail = [&](const std::string& reason) -> std::optional<std::string> {
        if (why) *why = reason;
        return std::nullopt;
    };
    if (name.empty()) return fail("no file name");
    fs::path p = absoluteIn(mFolder, name);
    std::error_code ec;
    if (fs::is_directory(p, ec)) return fail(p.string() + " is a folder");
    if (mKind == FileDialogKind::Open) {
        if (!fs::is_regular_file(p, ec)) return fail(p.string() + " does not exist");
    } else {
        if (!fs::is_directory(p.parent_path(), ec))
            return fail("no folder " + p.parent_path().string());
        if (!mDefaultExtension.empty() && !matchesExtension(p.filename().string(), mExtensions))
            p += mDefaultExtension;
        if (fs::is_directory(p, ec)) return fail(p.string() + " is a folder");
    }
    if (why) why->clear();
    return p.string();
}

std::optional<std::string> FileBrowser::confirm(std::string* why) {
    if (!name.empty()) {
        std::error_code ec;
        if (fs::is_directory(absoluteIn(mFolder, name), ec) && navigate(name)) {
            name.clear();
            if (why) why->clear();
            return std::nullopt;
        }
    }
    return resolve(why);
}

std::string FileBrowser::toString() const {
    return std::string("FileBrowser{") + (mKind == FileDialogKind::Open ? "open" : "save") + ", " +
           mFolder + ", name '" + name + "', " + std::to_string(mEntries.size()) + " entries" +
           (mError.empty() ? "" : ", error: " + mError) + "}";
}

// ---------------------------------------------------------------------------------------------
// Drawing.

FileDialogResult drawFileDialog(const char* title, FileBrowser& browser, std::string* chosen) {
    ImGui::SetNextWindowSize(ImVec2(560, 420), ImGuiCond_Appearing);
    if (!ImGui::BeginPopupModal(title, nullptr)) return FileDialogResult::Cancelled;
    std::string& message = browser.message;

    if (ImGui::ArrowButton("##up", ImGuiDir_Up)) browser.up();
    ImGui::SameLine();
    ImGui::TextUnformatted(browser.folder().c_str());
    if (!browser.error().empty())
        ImGui::TextColored(ImVec4(1, 0.4f, 0.4f, 1), "%s", browser.error().c_str());

    // The listing: a click picks, a double click enters a folder or confirms a file.
    bool confirmNow = false;
    const float footer = ImGui::GetFrameHeightWithSpacing() * 3 + 8;
    ImGui::BeginChild("##files", ImVec2(0, -footer), true);
    const std::vector<FileEntry> entries = browser.entries();  // activate may re-list
    for (const FileEntry& e : entries) {
        const std::string label = e.directory ? e.name + "/" : e.name;
        if (ImGui::Selectable(label.c_str(), !e.directory && e.name == browser.name,
                              ImGuiSelectableFlags_AllowDoubleClick)) {
            const bool twice = ImGui::IsMouseDoubleClicked(ImGuiMouseButton_Left);
            if (e.directory) {
                browser.activate(e);
                break;
            }
            browser.activate(e);
            if (twice) confirmNow = true;
        }
        if (!e.directory) {
            ImGui::SameLine(ImGui::GetWindowContentRegionMax().x - 90);
            ImGui::TextDisabled("%8.1f kB", static_cast<double>(e.size) / 1024.0);
        }
    }
    ImGui::EndChild();

    // The name field (Enter confirms).
    char buffer[1024];
    std::snprintf(buffer, sizeof buffer, "%s", browser.name.c_str());
    std::string filter;
    for (const std::string& e : browser.extensions()) filter += (filter.empty() ? "" : " ") + e;
    if (ImGui::InputText(filter.empty() ? "name" : filter.c_str(), buffer, sizeof buffer,
                         ImGuiInputTextFlags_EnterReturnsTrue))
        confirmNow = true;
    browser.name = buffer;
    if (!message.empty())
        ImGui::TextColored(ImVec4(1, 0.6f, 0.3f, 1), "%s", message.c_str());
    else
        ImGui::TextDisabled("%s", browser.kind() == FileDialogKind::Open ? "open" : "save");

    const bool ok = ImGui::Button("OK", ImVec2(90, 0));
    ImGui::SameLine();
    const bool cancel = ImGui::Button("Cancel", ImVec2(90, 0)) ||
                        ImGui::IsKeyPressed(ImGui::GetKeyIndex(ImGuiKey_Escape), false);
    FileDialogResult result = FileDialogResult::Open;
    if (ok || confirmNow) {
        std::string why;
        if (auto path = browser.confirm(&why)) {
            *chosen = *path;
            result = FileDialogResult::Confirmed;
        } else {
            message = why;
        }
    }
    if (cancel && result == FileDialogResult::Open) result = FileDialogResult::Cancelled;
    if (result != FileDialogResult::Open) ImGui::CloseCurrentPopup();
    ImGui::EndPopup();
    return result;
}

}  // namespace penumbra
