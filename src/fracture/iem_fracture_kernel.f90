!> The force kernel's fracture part (docs/model.md, "Fracture"): on a chunk of cells whose
!> elastic law is already evaluated, it finds the cells whose damage has begun or begins at
!> the trial strains, gives them the damaged cell law (each energy term scaled by the smallest
!> intact factor among the springs it uses) and, at an accepted state, commits their strain
!> history, the energy their damage dissipates and the times their springs fail. An intact
!> chunk costs one test of its strains against the onsets.
module iem_fracture_kernel
  use iem_kinds, only: wp
  use iem_spring_constants, only: cell_constants_t, law_bending
  use iem_fracture, only: fracture_t, edge_factor, shear_factor, intact_time
  use iem_fracture_law, only: fracture_law_t, crit_tension, crit_crushing, crit_shear, no_onset
  implicit none
  private
  public :: fracture_chunk, damaged_cell, chunk_intact, chunk_unhit

contains

  !> Damage of a chunk of m cells (the first is cell c_first) with edge strains ep(:, 4) and
  !> shear measures s(:, 4) whose elastic g, t and en are given: the damaged cells (dmg, n_dmg
  !> of them) get their intact edge factors fe and shear factors fs at the trial history
  !> (largest strains so far and now) and their g, t, en from damaged_cell. With accept the
  !> state is accepted at time: the history moves to it, the energy the new damage releases
  !> along the step (released_energy) is added to the cell's dissipation, and springs whose
  !> factor reached 0 get
  !> their failure time. k: the constants (of every cell, or ks(mat(c)) with several
  !> materials).
  pure subroutine fracture_chunk(fr, c_first, m, k, ep, s, accept, time, g, t, en, fe, fs, &
                                 dmg, n_dmg, ks, mat)
    type(fracture_t), intent(inout) :: fr
    integer, intent(in) :: c_first, m
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: ep(:, :), s(:, :)
    logical, intent(in) :: accept
    real(wp), intent(in) :: time
    real(wp), intent(inout) :: g(:, :), t(:, :), en(:)
    real(wp), intent(out) :: fe(:, :), fs(:, :)
    logical, intent(out) :: dmg(:)
    integer, intent(out) :: n_dmg
    type(cell_constants_t), intent(in), optional :: ks(:)
    integer, intent(in), optional :: mat(:)
    real(wp) :: kap(12), knew(12)
    integer :: c, q, cell, mc

    n_dmg = 0
    dmg(1:m) = .false.
    if (chunk_intact(fr, c_first, m, ep, s)) return
    mc = 1
    do c = 1, m
      cell = c_first + c - 1
      if (present(mat)) mc = mat(c)
      associate(lw => fr%laws(mc))
        kap = fr%kappa(:, cell)
        knew(1:4) = max(kap(1:4), ep(c, :))
        knew(5:8) = max(kap(5:8), -ep(c, :))
        knew(9:12) = max(kap(9:12), abs(s(c, :)))
        dmg(c) = fr%hit(cell) .or. any(knew(1:4) > lw%onset(crit_tension)) .or. &
                 any(knew(5:8) > lw%onset(crit_crushing)) .or. &
                 any(knew(9:12) > lw%onset(crit_shear))
        if (.not. dmg(c)) cycle
        n_dmg = n_dmg + 1
        do q = 1, 4
          fe(c, q) = edge_factor(lw, knew, q)
          fs(c, q) = shear_factor(lw, knew, q)
        end do
        if (present(ks)) then
          call damaged_cell(ks(mc), ep(c, :), s(c, :), fe(c, :), fs(c, :), g(c, :), t(c, :))
        else
          call damaged_cell(k, ep(c, :), s(c, :), fe(c, :), fs(c, :), g(c, :), t(c, :))
        end if
        en(c) = 0.5_wp*sum(g(c, :)*ep(c, :) + t(c, :)*s(c, :))
        if (.not. accept) cycle
        ! the energy the new damage releases along the step's strain path
        if (present(ks)) then
          call released_energy(ks(mc), lw, kap, fr%e_prev(:, cell), fr%hit(cell), ep(c, :), &
                               s(c, :), fr%diss(cell))
        else
          call released_energy(k, lw, kap, fr%e_prev(:, cell), fr%hit(cell), ep(c, :), &
                               s(c, :), fr%diss(cell))
        end if
        fr%e_prev(1:4, cell) = ep(c, :)
        fr%e_prev(5:8, cell) = s(c, :)
        fr%kappa(:, cell) = knew
        fr%hit(cell) = .true.
        fr%any_hit = .true.
        do q = 1, 4
          if (fe(c, q) == 0.0_wp .and. fr%t_fail(q, cell) == intact_time) &
            fr%t_fail(q, cell) = time
          if (fs(c, q) == 0.0_wp .and. fr%t_fail(4 + q, cell) == intact_time) &
            fr%t_fail(4 + q, cell) = time
        end do
      end associate
    end do
  end subroutine fracture_chunk

  !> True when no cell of the chunk of m cells from c_first has been hit and none of its edge
  !> strains ep(:, 4) and shear measures s(:, 4) passes the smallest onset of its kind (the
  !> chunk then keeps the elastic law and has nothing to commit): one test a criterion.
  pure logical function chunk_intact(fr, c_first, m, ep, s) result(intact)
    type(fracture_t), intent(in) :: fr
    integer, intent(in) :: c_first, m
    real(wp), intent(in) :: ep(:, :), s(:, :)
    integer :: c, q, n
    real(wp) :: on_t, on_c, on_s
    ! counts of comparisons (which vectorise, unlike a floating-point maximum): strains past
    ! the smallest onset of each criterion some material has
    intact = chunk_unhit(fr, c_first, m)
    if (.not. intact) return
    n = 0
    on_t = fr%onset_min(crit_tension)
    on_c = fr%onset_min(crit_crushing)
    on_s = fr%onset_min(crit_shear)
    if (on_t < no_onset) then
      do q = 1, 4
        do c = 1, m
          n = n + merge(1, 0, ep(c, q) > on_t)
        end do
      end do
    end if
    if (on_c < no_onset) then
      do q = 1, 4
        do c = 1, m
          n = n + merge(1, 0, -ep(c, q) > on_c)
        end do
      end do
    end if
    if (on_s < no_onset) then
      do q = 1, 4
        do c = 1, m
          n = n + merge(1, 0, abs(s(c, q)) > on_s)
        end do
      end do
    end if
    intact = n == 0
  end function chunk_intact

  !> True when the damage of none of the m cells from c_first on has begun.
  pure logical function chunk_unhit(fr, c_first, m) result(unhit)
    type(fracture_t), intent(in) :: fr
    integer, intent(in) :: c_first, m
    integer :: c, n
    unhit = .true.
    if (.not. fr%any_hit) return
    n = 0
    do c = c_first, c_first + m - 1
      n = n + merge(1, 0, fr%hit(c))
    end do
    unhit = n == 0
  end function chunk_unhit

  !> Add to diss the energy a cell of constants k and law lw releases by damage between its
  !> committed state (strain history kap, strains e_old = (ep, s) of its last accepted state
  !> when hit, else unknown) and the accepted strains ep, s: along the straight strain path
  !> between them, in pieces halved until the intact factors change by at most 0.001 in each
  !> and nearly linearly (a piece's midpoint within 1e-4 of the mean of its ends), each
  !> piece releases its factors' drop times the undamaged energy of the terms at the
  !> piece's middle (the midpoint rule; one piece in a step of a dynamic run). A cell not
  !> hit before starts its path where its first criterion reached its onset on the way to
  !> the new strains (proportional loading from there).
  pure subroutine released_energy(k, lw, kap, e_old, hit, ep, s, diss)
    type(cell_constants_t), intent(in) :: k
    type(fracture_law_t), intent(in) :: lw
    real(wp), intent(in) :: kap(12), e_old(8)
    ! (assumed shape: the kernel passes rows of its chunk arrays, 4 values each, uncopied)
    real(wp), intent(in) :: ep(:), s(:)
    logical, intent(in) :: hit
    real(wp), intent(inout) :: diss
    real(wp) :: e0(8), e1(8), em(8), lam, fa(8), fb(8), fm(8), g(4), t(4), ea, eb, sa, sb, ds
    integer :: q
    e1(1:4) = ep
    e1(5:8) = s
    if (hit) then
      e0 = e_old
    else
      lam = 0.0_wp
      do q = 1, 4
        lam = max(lam, ep(q)/lw%onset(crit_tension), -ep(q)/lw%onset(crit_crushing), &
                  abs(s(q))/lw%onset(crit_shear))
      end do
      e0 = e1/max(lam, 1.0_wp)
    end if
    fa = factors_at(e0)
    fb = factors_at(e1)
    if (all(fa == fb)) return
    ! pieces [sa, sb] of the path, each halved until its factors change by at most 0.01
    sa = 0.0_wp
    ds = 1.0_wp
    do while (sa < 1.0_wp)
      ds = min(2.0_wp*ds, 1.0_wp - sa)
      do
        sb = sa + ds
        if (sb >= 1.0_wp) sb = 1.0_wp
        fb = factors_at(e0 + sb*(e1 - e0))
        fm = factors_at(e0 + (0.5_wp*(sa + sb))*(e1 - e0))
        ! small drops, nearly linear along the piece (no end of softening inside it)
        if ((maxval(abs(fa - fb)) <= 1.0e-3_wp .and. maxval(abs(2.0_wp*fm - fa - fb)) <= &
             2.0e-4_wp) .or. ds < 1.0e-7_wp) exit
        ds = 0.5_wp*ds
      end do
      em = e0 + (0.5_wp*(sa + sb))*(e1 - e0)
      call damaged_cell(k, em(1:4), em(5:8), fa(1:4), fa(5:8), g, t)
      ea = 0.5_wp*(sum(g*em(1:4)) + sum(t*em(5:8)))
      call damaged_cell(k, em(1:4), em(5:8), fb(1:4), fb(5:8), g, t)
      eb = 0.5_wp*(sum(g*em(1:4)) + sum(t*em(5:8)))
      diss = diss + (ea - eb)
      fa = fb
      sa = sb
    end do

  contains

    !> The edge and shear factors at strains e on the path (history: kap and the path so far).
    pure function factors_at(e) result(f)
      real(wp), intent(in) :: e(8)
      real(wp) :: f(8), k_s(12)
      integer :: j
      k_s(1:4) = max(kap(1:4), e(1:4))
      k_s(5:8) = max(kap(5:8), -e(1:4))
      k_s(9:12) = max(kap(9:12), abs(e(5:8)))
      do j = 1, 4
        f(j) = edge_factor(lw, k_s, j)
        f(4 + j) = shear_factor(lw, k_s, j)
      end do
    end function factors_at
  end subroutine released_energy

  !> The damaged cell law of one cell: generalised stresses g(4) (edges) and t(4) (corners)
  !> for edge strains ep(4) and shear measures s(4) (or their rates), with intact factors
  !> fe(4) of the edges and fs(4) of the shear springs by their own criterion. Each energy
  !> term is scaled by the smallest factor among the springs it uses: the paper's cell, edge
  !> q by fe_q, the Poisson spring of corner q (edges q and q-1) by min(fe_q, fe_q-1), its
  !> shear spring by min(fs_q, fe_q, fe_q-1); the bending-corrected cell, whose x part is
  !> written as a term of each x edge plus a coupling term, each x edge's term by its factor
  !> and the coupling by sqrt(fe_1 fe_3) (y alike), its volume term by the least fe, its
  !> shear term by the least of all eight factors.
  pure subroutine damaged_cell(k, ep, s, fe, fs, g, t)
    type(cell_constants_t), intent(in) :: k
    ! (4 values each; assumed shape: the kernel passes rows of its chunk arrays, uncopied)
    real(wp), intent(in) :: ep(:), s(:), fe(:), fs(:)
    real(wp), intent(out) :: g(:), t(:)
    real(wp) :: fp(4), fx, fy, fv, fg, mx, my, gm, v, cc
    integer :: q, qm, qp
    if (k%law == law_bending) then
      ! x part 2ce mx^2 + cb dx^2 = 2cb (e1^2 + e3^2) + (ce/2 - cb) (e1 + e3)^2: a term of
      ! each edge (its own factor) and a coupling term (the geometric mean of the two: 0 when
      ! either edge failed, each edge's factor when they are equal); y alike
      fx = sqrt(fe(1)*fe(3))
      fy = sqrt(fe(2)*fe(4))
      fv = minval(fe)
      fg = min(fv, minval(fs))
      mx = ep(1) + ep(3)
      my = ep(2) + ep(4)
      gm = 0.25_wp*(s(1) - s(2) + s(3) - s(4))
      v = 2.0_wp*k%ch*fv*(mx + my)
      cc = k%ce - 2.0_wp*k%cb
      g = [4.0_wp*k%cb*fe(1)*ep(1) + cc*fx*mx + v, 4.0_wp*k%cb*fe(2)*ep(2) + cc*fy*my + v, &
           4.0_wp*k%cb*fe(3)*ep(3) + cc*fx*mx + v, 4.0_wp*k%cb*fe(4)*ep(4) + cc*fy*my + v]
      t = 2.0_wp*k%cg*fg*gm*[1.0_wp, -1.0_wp, 1.0_wp, -1.0_wp]
    else
      do q = 1, 4
        qm = modulo(q - 2, 4) + 1
        fp(q) = min(fe(q), fe(qm))
        t(q) = 2.0_wp*k%cg*min(fs(q), fp(q))*s(q)
      end do
      do q = 1, 4
        qm = modulo(q - 2, 4) + 1
        qp = modulo(q, 4) + 1
        g(q) = 2.0_wp*k%ce*fe(q)*ep(q) + 2.0_wp*k%ch*(fp(q)*(ep(q) + ep(qm)) + &
                                                      fp(qp)*(ep(qp) + ep(q)))
      end do
    end if
  end subroutine damaged_cell
end module iem_fracture_kernel
