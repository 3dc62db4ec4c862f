!> The cell laws of the force kernel, on a chunk of cells: the elastic law of the paper's
!> cell and of the bending-corrected cell (generalised stresses from edge strains and corner
!> shear measures, iem_spring_constants), the same cell by cell for several materials, and
!> the nonlinear (Masing) law of the paper's springs with its vectorisable fast path.
module iem_cell_laws
  use iem_kinds, only: wp, ip
  use iem_spring_constants, only: cell_constants_t, law_bending
  use iem_nonlinear_springs, only: nonlinear_springs_t, springs_per_cell, chunk_cells
  use iem_masing_fast, only: n_q, q_half_energy, masing_springs
  implicit none
  private
  public :: chunk, cell_law, cell_law_mixed, nonlinear_law

  !> Cells per chunk of the vectorised kernel: the chunk's work arrays stay in L1 cache.
  integer, parameter :: chunk = chunk_cells

contains
  !> The nonlinear law of the paper's cell on a chunk whose first cell is c_first: each
  !> spring's normalised stress psi from its committed history at its current strain (and,
  !> with accept, the history moved there), the generalised stresses g = 2 ce psi_edge +
  !> 2 ch (psi_Poisson at both ends of the edge), t = 2 cg psi_shear, and (unless energies is
  !> .false.; then en = 0) the work done on the cell's springs up to this state (trapezoidal
  !> increments from the committed state). The chunk's springs go through
  !> iem_nonlinear_springs' stress and commit (vectorised loops for the springs that stay on
  !> their curve, the state machine for the others), or, for springs that keep no curves
  !> (velocity Verlet), through masing_springs (chunk_springs).
  pure subroutine nonlinear_law(nl, c_first, m, ep, s, accept, g, t, en, mat, energies)
    type(nonlinear_springs_t), intent(inout) :: nl
    integer, intent(in) :: c_first, m
    real(wp), intent(in) :: ep(chunk, 4), s(chunk, 4)
    logical, intent(in) :: accept
    real(wp), intent(out) :: g(chunk, 4), t(chunk, 4), en(chunk)
    !> Material of each cell of the chunk (absent: material 1).
    integer, intent(in), optional :: mat(:)
    logical, intent(in), optional :: energies
    ! per spring k = 12 (c - 1) + j of the chunk (spring j of cell c): its stress and, for a
    ! chunk of several materials, its constants
    real(wp) :: psi(springs_per_cell*chunk), pm(springs_per_cell*chunk, n_q)
    integer :: c, k, mc
    logical :: want, mixed
    want = .true.
    if (present(energies)) want = energies
    mc = 1
    mixed = .false.
    if (present(mat)) then
      mc = mat(1)
      mixed = any(mat(1:m) /= mc)
    end if
    if (mixed) then
      ! each cell's rows of its material's table
      do c = 1, m
        k = springs_per_cell*(c - 1)
        pm(k + 1:k + springs_per_cell, :) = nl%q(k + 1:k + springs_per_cell, :, mat(c))
      end do
      call chunk_springs(nl, c_first, m, ep, s, accept, want, pm, psi, en)
    else
      call chunk_springs(nl, c_first, m, ep, s, accept, want, nl%q(:, :, mc), psi, en)
    end if
    mc = 1
    do c = 1, m
      if (present(mat)) mc = mat(c)
      k = springs_per_cell*(c - 1)
      ! g_q = 2 ce psi_q + 2 ch (psi_Poisson(q) + psi_Poisson(q + 1))
      g(c, 1) = nl%c2(1, mc)*psi(k + 1) + nl%c2(2, mc)*(psi(k + 5) + psi(k + 6))
      g(c, 2) = nl%c2(1, mc)*psi(k + 2) + nl%c2(2, mc)*(psi(k + 6) + psi(k + 7))
      g(c, 3) = nl%c2(1, mc)*psi(k + 3) + nl%c2(2, mc)*(psi(k + 7) + psi(k + 8))
      g(c, 4) = nl%c2(1, mc)*psi(k + 4) + nl%c2(2, mc)*(psi(k + 8) + psi(k + 5))
      t(c, 1) = nl%c2(3, mc)*psi(k + 9)
      t(c, 2) = nl%c2(3, mc)*psi(k + 10)
      t(c, 3) = nl%c2(3, mc)*psi(k + 11)
      t(c, 4) = nl%c2(3, mc)*psi(k + 12)
    end do
  end subroutine nonlinear_law

  !> The springs of nonlinear_law's chunk (spring k = 12 (c - 1) + j: spring j of cell c,
  !> constants p(k, :)): their stresses psi, with accept their commit, and with want the
  !> cells' energies en (else en = 0); with their curves (iem_nonlinear_springs) or, when
  !> the springs keep none, from the top of their stacks (masing_springs).
  pure subroutine chunk_springs(nl, c_first, m, ep, s, accept, want, p, psi, en)
    type(nonlinear_springs_t), intent(inout) :: nl
    integer, intent(in) :: c_first, m
    real(wp), intent(in) :: ep(chunk, 4), s(chunk, 4)
    logical, intent(in) :: accept, want
    real(wp), intent(in), contiguous :: p(:, :)
    real(wp), intent(out) :: psi(springs_per_cell*chunk), en(chunk)
    ! per spring: its strain, the work increment, the kind of its move, and the committed
    ! strain and stress it moved from
    real(wp) :: e(springs_per_cell*chunk), dw(springs_per_cell*chunk), mv(springs_per_cell*chunk)
    real(wp) :: e_old(springs_per_cell*chunk), psi_old(springs_per_cell*chunk)
    integer :: c, j, k, i0, n, n_slow
    i0 = springs_per_cell*(c_first - 1)
    n = springs_per_cell*m
    call nl%prepare(c_first, m, p)
    do c = 1, m
      ! the cell's spring strains (iem_nonlinear_springs' spring_strains)
      k = springs_per_cell*(c - 1)
      e(k + 1) = ep(c, 1)
      e(k + 2) = ep(c, 2)
      e(k + 3) = ep(c, 3)
      e(k + 4) = ep(c, 4)
      e(k + 5) = ep(c, 1) + ep(c, 4)
      e(k + 6) = ep(c, 2) + ep(c, 1)
      e(k + 7) = ep(c, 3) + ep(c, 2)
      e(k + 8) = ep(c, 4) + ep(c, 3)
      e(k + 9) = s(c, 1)
      e(k + 10) = s(c, 2)
      e(k + 11) = s(c, 3)
      e(k + 12) = s(c, 4)
    end do
    if (.not. nl%curves) then
      ! a run that commits every evaluation: from the top of each spring's stack
      associate(st => nl%state, j => i0 + 1, l => i0 + n)
        call masing_springs(n, int(st%depth), e, p, accept, st%strain(j:l), st%stress(j:l), &
                            st%dir(j:l), st%count(j:l), st%e_rev(:, j:l), st%s_rev(:, j:l), &
                            st%e_max_pos(j:l), st%e_max_neg(j:l), psi, e_old, psi_old)
      end associate
      if (accept .or. want) then
        do k = 1, n
          dw(k) = p(k, q_half_energy)*(psi_old(k) + psi(k))*(e(k) - e_old(k))
        end do
      end if
      if (accept) then
        do k = 1, n
          nl%work(i0 + k) = nl%work(i0 + k) + dw(k)
        end do
      end if
    else if (accept) then
      ! with the springs' curves; a commit gives the stresses too, and adds the work
      call nl%commit(i0, n, e, p, psi)
    else
      call nl%stress(i0, n, e, p, psi, mv, n_slow)
      if (want) then
        do k = 1, n
          dw(k) = p(k, q_half_energy)*(nl%state%stress(i0 + k) + psi(k))* &
                  (e(k) - nl%state%strain(i0 + k))
        end do
      end if
    end if
    ! the work of each cell, summed in the order of its springs (with accept, the work moved
    ! to this state)
    en(1:m) = 0.0_wp
    if (.not. want) return
    do c = 1, m
      k = springs_per_cell*(c - 1)
      if (accept) then
        do j = 1, springs_per_cell
          en(c) = en(c) + nl%work(i0 + k + j)
        end do
      else
        do j = 1, springs_per_cell
          en(c) = en(c) + nl%work(i0 + k + j) + dw(k + j)
        end do
      end if
    end do
  end subroutine chunk_springs

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
end module iem_cell_laws
