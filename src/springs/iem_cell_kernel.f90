!> Force kernel of the IEM cell: edge, Poisson and shear springs measured on the current
!> geometry (edge lengths and corner angles), so any rigid motion gives zero force.
!>
!> Strain measures (docs/model.md): edge q, from corner q to corner q+1, has the engineering
!> strain eps_q = l_q/l0_q - 1; corner q (edges q and q-1) has the shear measure
!> s_q = sin(gamma_q) = cos(theta_q), gamma_q = pi/2 - theta_q, computed from the unit edge
!> vectors without any angle function. s = gamma - gamma^3/6 + ..., so the tangent is that of
!> the angle and the shear stress differs from the angle form by gamma^2/6 (2e-5 at 1% shear).
!> The cell law maps (eps, s) linearly to generalised stresses (g, t) = dPi/d(eps, s): the
!> paper's springs or the bending-corrected cell (iem_spring_constants).
module iem_cell_kernel
  use iem_kinds, only: wp
  use iem_spring_constants, only: cell_constants_t, law_bending
  use iem_nonlinear_springs, only: nonlinear_springs_t, springs_per_cell, spring_kind, &
                                   spring_strains
  use iem_masing, only: masing_trial, masing_commit, masing_mirror_strain
  use iem_kinds, only: ip
  use iem_fracture, only: fracture_t
  use iem_fracture_kernel, only: fracture_chunk, damaged_cell
  implicit none
  private
  public :: cell_energy, cell_force, cell_forces, cell_strain_measures

  !> Cells per chunk of the vectorised kernel: the chunk's work arrays stay in L1 cache.
  integer, parameter :: chunk = 64

contains

  !> Strain energy of one cell (J) for corner displacements u(2, 4).
  pure real(wp) function cell_energy(k, u) result(en)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: u(2, 4)
    real(wp) :: v(2, 4), f(2, 4), p
    v = 0.0_wp
    call cell_force(k, u, v, 0.0_wp, f, en, p)
  end function cell_energy

  !> Edge strains ep(4) (bottom, right, top, left) and corner shear measures s(4) (SW, SE,
  !> NE, NW) of one cell for corner displacements u(2, 4), as the force kernel measures them.
  pure subroutine cell_strain_measures(k, u, ep, s)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: u(2, 4)
    real(wp), intent(out) :: ep(4), s(4)
    real(wp) :: e(2, 4), len(4)
    integer :: q
    e(:, 1) = [k%lx, 0.0_wp] + u(:, 2) - u(:, 1)
    e(:, 2) = [0.0_wp, k%ly] + u(:, 3) - u(:, 2)
    e(:, 3) = [-k%lx, 0.0_wp] + u(:, 4) - u(:, 3)
    e(:, 4) = [0.0_wp, -k%ly] + u(:, 1) - u(:, 4)
    do q = 1, 4
      len(q) = sqrt(sum(e(:, q)**2))
      ep(q) = len(q)*k%il0(q) - 1.0_wp
      e(:, q) = e(:, q)/len(q)
    end do
    ! corner q joins edge q and edge q-1
    s(1) = -dot_product(e(:, 1), e(:, 4))
    s(2) = -dot_product(e(:, 2), e(:, 1))
    s(3) = -dot_product(e(:, 3), e(:, 2))
    s(4) = -dot_product(e(:, 4), e(:, 3))
  end subroutine cell_strain_measures

  !> Internal force f(2, 4) = dPi/dx of one cell, plus the stiffness-proportional damping force
  !> beta*K*v when beta > 0; returns the strain energy and the damping power f_damp . v.
  pure subroutine cell_force(k, u, v, beta, f, energy, damp_power)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: u(2, 4), v(2, 4), beta
    real(wp), intent(out) :: f(2, 4), energy, damp_power
    integer, parameter :: nodes(4, 1) = reshape([1, 2, 3, 4], [4, 1])
    real(wp) :: y(4, 4)
    y(1:2, :) = u
    y(3:4, :) = v
    call cell_forces(k, nodes, 4, y, beta, f, energy, damp_power)
  end subroutine cell_force

  !> Nodal forces f(2, :) (internal + stiffness damping) of many cells for the state
  !> y(4, :) = (u, v) of the nodes listed in cell_nodes, with the strain energy and the
  !> damping power summed over the counted cells (those whose first corner is among the
  !> first n_owned nodes). Each node's force is summed over its cells in
  !> the order of cell_nodes' columns, so the same cells in the same order give bitwise the same
  !> forces whatever else the list holds. Cells go in chunks whose corner values are first
  !> gathered into small unit-stride arrays, so the compiler vectorises the kernel.
  !> The stiffness damping acts on the velocities in rows damp_row:damp_row+1 of y (default 3,
  !> the velocities themselves; 5 for the filtered velocities of capped damping); the damping
  !> power is always taken with the velocities (rows 3:4). With nl (nonlinear springs of the
  !> paper's cell, one set per column of cell_nodes) the springs follow their Masing law from
  !> their committed state; with commit = .true. this state y is accepted: every spring's
  !> history moves to it. The energy is then the work done on the springs (stored plus
  !> dissipated), and stiffness damping uses the initial (elastic) stiffness. With ks and
  !> cell_mat (several materials), cell c follows the constants ks(cell_mat(c)) (and its
  !> material's nonlinear law); k then gives only the geometry (lx, ly, il0), the same for all.
  !> With cell_energy and cell_power (one entry a cell; an empty array: not kept), each
  !> cell's energy and (when beta > 0) damping power are also stored (for sums that do not
  !> depend on how the cells are split among ranks). With fr (fracture) the cells whose damage
  !> has begun or begins follow the damaged law, and with commit their damage is committed at
  !> time (iem_fracture_kernel).
  pure subroutine cell_forces(k, cell_nodes, n_owned, y, beta, f, energy, damp_power, damp_row, &
                              nl, commit, ks, cell_mat, cell_energy, cell_power, fr, time)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: cell_nodes(:, :)
    !> A cell is counted when its first corner is one of the nodes 1..n_owned.
    integer, intent(in) :: n_owned
    real(wp), intent(in) :: y(:, :), beta
    real(wp), intent(out) :: f(:, :), energy, damp_power
    integer, intent(in), optional :: damp_row
    type(nonlinear_springs_t), intent(inout), optional :: nl
    logical, intent(in), optional :: commit
    type(cell_constants_t), intent(in), optional :: ks(:)
    integer, intent(in), optional :: cell_mat(:)
    real(wp), intent(out), optional :: cell_energy(:), cell_power(:)
    type(fracture_t), intent(inout), optional :: fr
    real(wp), intent(in), optional :: time
    real(wp) :: ux(chunk, 4), uy(chunk, 4), vx(chunk, 4), vy(chunk, 4), px(chunk, 4), py(chunk, 4)
    real(wp) :: fx(chunk, 4), fy(chunk, 4), en(chunk), pw(chunk)
    integer :: c0, m, c, q, nc, node, row
    logical :: damped, filtered, accept, keep_energy, keep_power

    nc = size(cell_nodes, 2)
    keep_energy = .false.
    keep_power = .false.
    if (present(cell_energy)) keep_energy = size(cell_energy) >= nc
    if (present(cell_power)) keep_power = size(cell_power) >= nc .and. beta > 0.0_wp
    accept = .false.
    if (present(commit)) accept = commit
    damped = beta > 0.0_wp
    row = 3
    if (present(damp_row)) row = damp_row
    filtered = damped .and. row /= 3
    vx = 0.0_wp
    vy = 0.0_wp
    px = 0.0_wp
    py = 0.0_wp
    f = 0.0_wp
    energy = 0.0_wp
    damp_power = 0.0_wp
    do c0 = 1, nc, chunk
      m = min(chunk, nc - c0 + 1)
      do q = 1, 4
        do c = 1, m
          ux(c, q) = y(1, cell_nodes(q, c0 + c - 1))
          uy(c, q) = y(2, cell_nodes(q, c0 + c - 1))
        end do
      end do
      if (damped) then
        do q = 1, 4
          do c = 1, m
            vx(c, q) = y(row, cell_nodes(q, c0 + c - 1))
            vy(c, q) = y(row + 1, cell_nodes(q, c0 + c - 1))
          end do
        end do
      end if
      if (filtered) then
        do q = 1, 4
          do c = 1, m
            px(c, q) = y(3, cell_nodes(q, c0 + c - 1))
            py(c, q) = y(4, cell_nodes(q, c0 + c - 1))
          end do
        end do
      end if
      if (present(fr)) then
        if (present(ks) .and. present(cell_mat)) then
          call chunk_forces(k, m, damped, filtered, beta, ux, uy, vx, vy, px, py, fx, fy, en, &
                            pw, c_first=c0, accept=accept, ks=ks, mat=cell_mat(c0:c0 + m - 1), &
                            fr=fr, time=time)
        else
          call chunk_forces(k, m, damped, filtered, beta, ux, uy, vx, vy, px, py, fx, fy, en, &
                            pw, c_first=c0, accept=accept, fr=fr, time=time)
        end if
      else if (present(ks) .and. present(cell_mat)) then
        if (present(nl)) then
          call chunk_forces(k, m, damped, filtered, beta, ux, uy, vx, vy, px, py, fx, fy, en, &
                            pw, nl, c0, accept, ks, cell_mat(c0:c0 + m - 1))
        else
          call chunk_forces(k, m, damped, filtered, beta, ux, uy, vx, vy, px, py, fx, fy, en, &
                            pw, ks=ks, mat=cell_mat(c0:c0 + m - 1))
        end if
      else if (present(nl)) then
        call chunk_forces(k, m, damped, filtered, beta, ux, uy, vx, vy, px, py, fx, fy, en, pw, &
                          nl, c0, accept)
      else
        call chunk_forces(k, m, damped, filtered, beta, ux, uy, vx, vy, px, py, fx, fy, en, pw)
      end if
      do c = 1, m
        do q = 1, 4
          node = cell_nodes(q, c0 + c - 1)
          f(1, node) = f(1, node) + fx(c, q)
          f(2, node) = f(2, node) + fy(c, q)
        end do
        if (cell_nodes(1, c0 + c - 1) <= n_owned) then
          energy = energy + en(c)
          damp_power = damp_power + pw(c)
        end if
      end do
      if (keep_energy) cell_energy(c0:c0 + m - 1) = en(1:m)
      if (keep_power) cell_power(c0:c0 + m - 1) = pw(1:m)
    end do
  end subroutine cell_forces

  !> Kernel over one chunk of m cells with corner values in unit-stride arrays (cell index
  !> first), as branch-free loops the compiler vectorises: geometry and strain measures; the
  !> cell law; fracture (only with fr); damping (only when damped); corner forces.
  pure subroutine chunk_forces(k, m, damped, filtered, beta, ux, uy, vx, vy, px, py, fx, fy, &
                               en, pw, nl, c_first, accept, ks, mat, fr, time)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    logical, intent(in) :: damped, filtered
    real(wp), intent(in) :: beta
    real(wp), intent(in) :: ux(chunk, 4), uy(chunk, 4), vx(chunk, 4), vy(chunk, 4)
    real(wp), intent(in) :: px(chunk, 4), py(chunk, 4)
    real(wp), intent(out) :: fx(chunk, 4), fy(chunk, 4), en(chunk), pw(chunk)
    !> Nonlinear springs, the index of the chunk's first cell, and whether to commit.
    type(nonlinear_springs_t), intent(inout), optional :: nl
    integer, intent(in), optional :: c_first
    logical, intent(in), optional :: accept
    !> Several materials: the constants of each and the material of each cell of the chunk.
    type(cell_constants_t), intent(in), optional :: ks(:)
    integer, intent(in), optional :: mat(:)
    !> Fracture state and the time of the state (committed with accept).
    type(fracture_t), intent(inout), optional :: fr
    real(wp), intent(in), optional :: time
    ! per cell: unit edge vectors e, shear gradients a (d s/d a) and b (d s/d b), strains ep
    ! and shear measures s, generalised stresses g (edges) and t (corners), and the rates
    real(wp) :: ex(chunk, 4), ey(chunk, 4), ax(chunk, 4), ay(chunk, 4)
    real(wp) :: bx(chunk, 4), by(chunk, 4), ep(chunk, 4), s(chunk, 4), g(chunk, 4), t(chunk, 4)
    real(wp) :: d(chunk, 4), r(chunk, 4), gd(chunk, 4), td(chunk, 4)
    real(wp) :: e1x, e1y, e2x, e2y, e3x, e3y, e4x, e4y, l1, l2, l3, l4, i1, i2, i3, i4
    real(wp) :: s1, s2, s3, s4, ilx, ily
    real(wp) :: fe(chunk, 4), fs(chunk, 4)
    logical :: dmg(chunk)
    integer :: c, n_dmg

    ilx = k%il0(1)
    ily = k%il0(2)
    do c = 1, m
      ! edge vectors (current), lengths, unit vectors, strains
      e1x = k%lx + ux(c, 2) - ux(c, 1)
      e1y = uy(c, 2) - uy(c, 1)
      e2x = ux(c, 3) - ux(c, 2)
      e2y = k%ly + uy(c, 3) - uy(c, 2)
      e3x = -k%lx + ux(c, 4) - ux(c, 3)
      e3y = uy(c, 4) - uy(c, 3)
      e4x = ux(c, 1) - ux(c, 4)
      e4y = -k%ly + uy(c, 1) - uy(c, 4)
      l1 = sqrt(e1x**2 + e1y**2)
      l2 = sqrt(e2x**2 + e2y**2)
      l3 = sqrt(e3x**2 + e3y**2)
      l4 = sqrt(e4x**2 + e4y**2)
      i1 = 1.0_wp/l1
      i2 = 1.0_wp/l2
      i3 = 1.0_wp/l3
      i4 = 1.0_wp/l4
      ep(c, :) = [l1*ilx - 1.0_wp, l2*ily - 1.0_wp, l3*ilx - 1.0_wp, l4*ily - 1.0_wp]
      e1x = e1x*i1
      e1y = e1y*i1
      e2x = e2x*i2
      e2y = e2y*i2
      e3x = e3x*i3
      e3y = e3y*i3
      e4x = e4x*i4
      e4y = e4y*i4
      ! shear measures s = sin(gamma) at corners 1..4 (corner q joins edges q and q-1)
      s1 = -(e1x*e4x + e1y*e4y)
      s2 = -(e2x*e1x + e2y*e1y)
      s3 = -(e3x*e2x + e3y*e2y)
      s4 = -(e4x*e3x + e4y*e3y)
      s(c, :) = [s1, s2, s3, s4]
      ex(c, :) = [e1x, e2x, e3x, e4x]
      ey(c, :) = [e1y, e2y, e3y, e4y]
      ! d s_q / d a (a: edge q) and d s_q / d b (b: reversed edge q-1)
      ax(c, :) = [(-e4x - s1*e1x)*i1, (-e1x - s2*e2x)*i2, (-e2x - s3*e3x)*i3, (-e3x - s4*e4x)*i4]
      ay(c, :) = [(-e4y - s1*e1y)*i1, (-e1y - s2*e2y)*i2, (-e2y - s3*e3y)*i3, (-e3y - s4*e4y)*i4]
      bx(c, :) = [(e1x + s1*e4x)*i4, (e2x + s2*e1x)*i1, (e3x + s3*e2x)*i2, (e4x + s4*e3x)*i3]
      by(c, :) = [(e1y + s1*e4y)*i4, (e2y + s2*e1y)*i1, (e3y + s3*e2y)*i2, (e4y + s4*e3y)*i3]
    end do
    if (present(nl)) then
      call nonlinear_law(nl, c_first, m, ep, s, accept, g, t, en, mat)
    else
      if (present(ks)) then
        call cell_law_mixed(ks, mat, m, ep, s, g, t)
      else
        call cell_law(k, m, ep, s, g, t)
      end if
      do c = 1, m
        en(c) = 0.5_wp*sum(g(c, :)*ep(c, :) + t(c, :)*s(c, :))
      end do
    end if
    n_dmg = 0
    if (present(fr)) then
      if (present(ks)) then
        call fracture_chunk(fr, c_first, m, k, ep, s, accept, time, g, t, en, fe, fs, dmg, &
                            n_dmg, ks, mat)
      else
        call fracture_chunk(fr, c_first, m, k, ep, s, accept, time, g, t, en, fe, fs, dmg, &
                            n_dmg)
      end if
    end if
    pw(1:m) = 0.0_wp
    if (damped) then
      call strain_rates(vx, vy, d, r)
      if (present(ks)) then
        call cell_law_mixed(ks, mat, m, d, r, gd, td)
      else
        call cell_law(k, m, d, r, gd, td)
      end if
      if (n_dmg > 0) then
        do c = 1, m
          if (.not. dmg(c)) cycle
          if (present(ks)) then
            call damaged_cell(ks(mat(c)), d(c, :), r(c, :), fe(c, :), fs(c, :), gd(c, :), &
                              td(c, :))
          else
            call damaged_cell(k, d(c, :), r(c, :), fe(c, :), fs(c, :), gd(c, :), td(c, :))
          end if
        end do
      end if
      ! the damping power is f_damp . v: with filtered damping velocities, the strain rates of
      ! the velocities themselves are needed too
      if (filtered) call strain_rates(px, py, d, r)
      do c = 1, m
        pw(c) = beta*sum(gd(c, :)*d(c, :) + td(c, :)*r(c, :))
        g(c, :) = g(c, :) + beta*gd(c, :)
        t(c, :) = t(c, :) + beta*td(c, :)
      end do
    end if
    do c = 1, m
      ! edge forces per unit reference length along the unit vectors: corner q+1 gets
      ! +g_q e_q + t_q a_q, corner q gets -g_q e_q - t_q (a_q + b_q), corner q-1 gets t_q b_q
      g(c, :) = g(c, :)*[ilx, ily, ilx, ily]
      fx(c, 1) = -g(c, 1)*ex(c, 1) - t(c, 1)*(ax(c, 1) + bx(c, 1)) + g(c, 4)*ex(c, 4) &
                 + t(c, 4)*ax(c, 4) + t(c, 2)*bx(c, 2)
      fy(c, 1) = -g(c, 1)*ey(c, 1) - t(c, 1)*(ay(c, 1) + by(c, 1)) + g(c, 4)*ey(c, 4) &
                 + t(c, 4)*ay(c, 4) + t(c, 2)*by(c, 2)
      fx(c, 2) = -g(c, 2)*ex(c, 2) - t(c, 2)*(ax(c, 2) + bx(c, 2)) + g(c, 1)*ex(c, 1) &
                 + t(c, 1)*ax(c, 1) + t(c, 3)*bx(c, 3)
      fy(c, 2) = -g(c, 2)*ey(c, 2) - t(c, 2)*(ay(c, 2) + by(c, 2)) + g(c, 1)*ey(c, 1) &
                 + t(c, 1)*ay(c, 1) + t(c, 3)*by(c, 3)
      fx(c, 3) = -g(c, 3)*ex(c, 3) - t(c, 3)*(ax(c, 3) + bx(c, 3)) + g(c, 2)*ex(c, 2) &
                 + t(c, 2)*ax(c, 2) + t(c, 4)*bx(c, 4)
      fy(c, 3) = -g(c, 3)*ey(c, 3) - t(c, 3)*(ay(c, 3) + by(c, 3)) + g(c, 2)*ey(c, 2) &
                 + t(c, 2)*ay(c, 2) + t(c, 4)*by(c, 4)
      fx(c, 4) = -g(c, 4)*ex(c, 4) - t(c, 4)*(ax(c, 4) + bx(c, 4)) + g(c, 3)*ex(c, 3) &
                 + t(c, 3)*ax(c, 3) + t(c, 1)*bx(c, 1)
      fy(c, 4) = -g(c, 4)*ey(c, 4) - t(c, 4)*(ay(c, 4) + by(c, 4)) + g(c, 3)*ey(c, 3) &
                 + t(c, 3)*ay(c, 3) + t(c, 1)*by(c, 1)
    end do
  contains

    !> Edge strain rates d and shear rates r of the chunk's cells for corner velocities.
    pure subroutine strain_rates(wx, wy, d_, r_)
      real(wp), intent(in) :: wx(chunk, 4), wy(chunk, 4)
      real(wp), intent(out) :: d_(chunk, 4), r_(chunk, 4)
      real(wp) :: q1x, q1y, q2x, q2y, q3x, q3y, q4x, q4y
      integer :: i
      do i = 1, m
        q1x = wx(i, 2) - wx(i, 1)
        q1y = wy(i, 2) - wy(i, 1)
        q2x = wx(i, 3) - wx(i, 2)
        q2y = wy(i, 3) - wy(i, 2)
        q3x = wx(i, 4) - wx(i, 3)
        q3y = wy(i, 4) - wy(i, 3)
        q4x = wx(i, 1) - wx(i, 4)
        q4y = wy(i, 1) - wy(i, 4)
        d_(i, :) = [(ex(i, 1)*q1x + ey(i, 1)*q1y)*ilx, (ex(i, 2)*q2x + ey(i, 2)*q2y)*ily, &
                    (ex(i, 3)*q3x + ey(i, 3)*q3y)*ilx, (ex(i, 4)*q4x + ey(i, 4)*q4y)*ily]
        r_(i, :) = [ax(i, 1)*q1x + ay(i, 1)*q1y - bx(i, 1)*q4x - by(i, 1)*q4y, &
                    ax(i, 2)*q2x + ay(i, 2)*q2y - bx(i, 2)*q1x - by(i, 2)*q1y, &
                    ax(i, 3)*q3x + ay(i, 3)*q3y - bx(i, 3)*q2x - by(i, 3)*q2y, &
                    ax(i, 4)*q4x + ay(i, 4)*q4y - bx(i, 4)*q3x - by(i, 4)*q3y]
      end do
    end subroutine strain_rates
  end subroutine chunk_forces

  !> The nonlinear law of the paper's cell on a chunk whose first cell is c_first: each
  !> spring's normalised stress psi from its committed history at its current strain (and,
  !> with accept, the history moved there), the generalised stresses g = 2 ce psi_edge +
  !> 2 ch (psi_Poisson at both ends of the edge), t = 2 cg psi_shear, and the work done on the
  !> cell's springs up to this state (trapezoidal increments from the committed state).
  pure subroutine nonlinear_law(nl, c_first, m, ep, s, accept, g, t, en, mat)
    type(nonlinear_springs_t), intent(inout) :: nl
    integer, intent(in) :: c_first, m
    real(wp), intent(in) :: ep(chunk, 4), s(chunk, 4)
    logical, intent(in) :: accept
    real(wp), intent(out) :: g(chunk, 4), t(chunk, 4), en(chunk)
    !> Material of each cell of the chunk (absent: material 1).
    integer, intent(in), optional :: mat(:)
    real(wp) :: e(springs_per_cell), psi(springs_per_cell), tan, dw, e_old, psi_old, er, x
    integer :: c, j, i, kind, mc
    logical :: fast
    mc = 1
    do c = 1, m
      if (present(mat)) mc = mat(c)
      e = spring_strains(ep(c, :), s(c, :))
      en(c) = 0.0_wp
      do j = 1, springs_per_cell
        i = springs_per_cell*(c_first + c - 2) + j
        kind = spring_kind(j)
        associate(st => nl%state)
          e_old = st%strain(i)
          psi_old = st%stress(i)
          fast = .true.
          if (e(j) == e_old) then
            psi(j) = psi_old
          else if (st%count(i) == 0 .and. (st%dir(i) == 0 .or. &
                   real(st%dir(i), wp)*(e(j) - e_old) > 0.0_wp)) then
            ! fast path: a spring on its skeleton that keeps going the same way
            er = merge(nl%er_pos(kind, mc), nl%er_neg(kind, mc), e(j) >= 0.0_wp)
            psi(j) = e(j)/(1.0_wp + abs(e(j))/er)
          else if (on_branch(st%count(i), st%dir(i), e(j), e_old, st%e_rev(:, i), &
                             nl%er_pos(kind, mc), nl%er_neg(kind, mc))) then
            ! fast path: a spring that keeps going the same way on its current Masing branch,
            ! short of the point where that branch ends (as masing_trial would find)
            associate(n => st%count(i))
              x = 0.5_wp*(e(j) - st%e_rev(n, i))
              psi(j) = st%s_rev(n, i) + 2.0_wp*(x/(1.0_wp + abs(x)/ &
                       (0.5_wp*(nl%er_pos(kind, mc) + nl%er_neg(kind, mc)))))
            end associate
          else
            fast = .false.
          end if
          if (accept) then
            if (fast) then
              ! no reversal and no branch ends: the commit moves along the same curve (what
              ! masing_commit does in this case, bit for bit)
              if (e(j) /= e_old) then
                st%dir(i) = merge(1_ip, -1_ip, e(j) > e_old)
                st%strain(i) = e(j)
                st%stress(i) = psi(j)
                st%e_max_pos(i) = max(st%e_max_pos(i), e(j))
                st%e_max_neg(i) = min(st%e_max_neg(i), e(j))
              end if
            else
              call masing_commit(e(j), 1.0_wp, nl%er_pos(kind, mc), nl%er_neg(kind, mc), &
                                 st%strain(i), st%stress(i), st%dir(i), st%count(i), &
                                 st%e_rev(:, i), st%s_rev(:, i), st%e_max_pos(i), &
                                 st%e_max_neg(i))
              ! the committed stress is bit for bit the trial stress at the same strain
              psi(j) = st%stress(i)
            end if
          else if (.not. fast) then
            call masing_trial(e(j), 1.0_wp, nl%er_pos(kind, mc), nl%er_neg(kind, mc), &
                              st%strain(i), st%stress(i), st%dir(i), st%count(i), st%e_rev(:, i), &
                              st%s_rev(:, i), psi(j), tan)
          end if
          dw = 0.5_wp*nl%c2(kind, mc)*(psi_old + psi(j))*(e(j) - e_old)
          if (accept) then
            nl%work(i) = nl%work(i) + dw
            en(c) = en(c) + nl%work(i)
          else
            en(c) = en(c) + nl%work(i) + dw
          end if
        end associate
      end do
      g(c, :) = nl%c2(1, mc)*psi(1:4) + nl%c2(2, mc)*(psi(5:8) + cshift(psi(5:8), 1))
      t(c, :) = nl%c2(3, mc)*psi(9:12)
    end do
  end subroutine nonlinear_law

  !> Whether a spring with n > 0 reversal points, last moving in direction dir from its
  !> committed strain e_c, reaches the trial strain e by going on along its current branch
  !> (the one from reversal point n) without passing that branch's aim: the previous reversal
  !> point, or for n = 1 the mirror of the first one (docs/nonlinear.md, section 4).
  pure logical function on_branch(n, dir, e, e_c, e_rev, er_pos, er_neg)
    integer(ip), intent(in) :: n, dir
    real(wp), intent(in) :: e, e_c, e_rev(:), er_pos, er_neg
    real(wp) :: aim
    integer :: d
    on_branch = .false.
    if (n <= 0 .or. dir == 0) return
    if (real(dir, wp)*(e - e_c) <= 0.0_wp) return
    if (n >= 2) then
      aim = e_rev(n - 1)
      d = merge(1, -1, aim > e_rev(n))
    else
      aim = masing_mirror_strain(e_rev(1), er_pos, er_neg)
      d = merge(-1, 1, e_rev(1) > 0.0_wp)
    end if
    on_branch = d == dir .and. real(d, wp)*(e - aim) < 0.0_wp
  end function on_branch

  !> The elastic cell law on a chunk: generalised stresses g = dPi/d eps (edges) and
  !> t = dPi/d s (corners) from edge strains ep and corner shear measures s.
  pure subroutine cell_law(k, m, ep, s, g, t)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    real(wp), intent(in) :: ep(chunk, 4), s(chunk, 4)
    real(wp), intent(out) :: g(chunk, 4), t(chunk, 4)
    real(wp) :: ce2, ch2, cg2, mx, my, sx, sy, dx, dy, gm
    integer :: c
    if (k%law == law_bending) then
      ! Pi = 2ce(mx^2+my^2) + 4ch(mx+my)^2 + 4cg gm^2 + cb(dx^2+dy^2): mean strains mx, my, mean
      ! shear gm (signs that make a uniform shear equal at every corner), bending measures
      ! dx = eps_top - eps_bottom, dy = eps_right - eps_left
      do c = 1, m
        mx = 0.5_wp*(ep(c, 1) + ep(c, 3))
        my = 0.5_wp*(ep(c, 2) + ep(c, 4))
        dx = ep(c, 3) - ep(c, 1)
        dy = ep(c, 2) - ep(c, 4)
        gm = 0.25_wp*(s(c, 1) - s(c, 2) + s(c, 3) - s(c, 4))
        sx = 2.0_wp*k%ce*mx + 4.0_wp*k%ch*(mx + my)
        sy = 2.0_wp*k%ce*my + 4.0_wp*k%ch*(mx + my)
        g(c, :) = [sx - 2.0_wp*k%cb*dx, sy + 2.0_wp*k%cb*dy, sx + 2.0_wp*k%cb*dx, &
                   sy - 2.0_wp*k%cb*dy]
        t(c, :) = 2.0_wp*k%cg*gm*[1.0_wp, -1.0_wp, 1.0_wp, -1.0_wp]
      end do
    else
      ce2 = 2.0_wp*k%ce
      ch2 = 2.0_wp*k%ch
      cg2 = 2.0_wp*k%cg
      do c = 1, m
        g(c, :) = [ce2*ep(c, 1) + ch2*(2.0_wp*ep(c, 1) + ep(c, 4) + ep(c, 2)), &
                   ce2*ep(c, 2) + ch2*(2.0_wp*ep(c, 2) + ep(c, 1) + ep(c, 3)), &
                   ce2*ep(c, 3) + ch2*(2.0_wp*ep(c, 3) + ep(c, 2) + ep(c, 4)), &
                   ce2*ep(c, 4) + ch2*(2.0_wp*ep(c, 4) + ep(c, 3) + ep(c, 1))]
        t(c, :) = cg2*s(c, :)
      end do
    end if
  end subroutine cell_law

  !> The elastic cell law on a chunk of cells of several materials: cell c follows the
  !> constants ks(mat(c)) (the same arithmetic as cell_law, cell by cell).
  pure subroutine cell_law_mixed(ks, mat, m, ep, s, g, t)
    type(cell_constants_t), intent(in) :: ks(:)
    integer, intent(in) :: mat(:), m
    real(wp), intent(in) :: ep(chunk, 4), s(chunk, 4)
    real(wp), intent(out) :: g(chunk, 4), t(chunk, 4)
    real(wp) :: e1(chunk, 4), s1(chunk, 4), g1(chunk, 4), t1(chunk, 4)
    integer :: c
    e1 = 0.0_wp
    s1 = 0.0_wp
    do c = 1, m
      e1(1, :) = ep(c, :)
      s1(1, :) = s(c, :)
      call cell_law(ks(mat(c)), 1, e1, s1, g1, t1)
      g(c, :) = g1(1, :)
      t(c, :) = t1(1, :)
    end do
  end subroutine cell_law_mixed
end module iem_cell_kernel
