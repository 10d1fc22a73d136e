#pragma once
// The six rigid-body degrees of freedom, always in the order Dx Dy Dz Rx Ry Rz (SPEC §1).

#include <array>
#include <optional>
#include <string>
#include <string_view>

namespace stagefit {

enum class Dof : int { kDx = 0, kDy = 1, kDz = 2, kRx = 3, kRy = 4, kRz = 5 };

inline constexpr std::array<Dof, 6> kAllDofs = {Dof::kDx, Dof::kDy, Dof::kDz,
                                                Dof::kRx, Dof::kRy, Dof::kRz};
inline constexpr std::array<std::string_view, 6> kDofNames = {"Dx", "Dy", "Dz", "Rx", "Ry", "Rz"};

inline int index(Dof dof) { return static_cast<int>(dof); }
inline std::string_view name(Dof dof) { return kDofNames[index(dof)]; }
inline bool is_rotation(Dof dof) { return index(dof) >= 3; }

/// "Dx".."Rz" (case-sensitive) to the DoF; nullopt for anything else.
inline std::optional<Dof> ParseDof(std::string_view text) {
  for (int i = 0; i < 6; ++i) {
    if (kDofNames[i] == text) return static_cast<Dof>(i);
  }
  return std::nullopt;
}

}  // namespace stagefit
