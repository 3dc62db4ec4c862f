!> RK4's stages as one wavefront over the bands of a rank's chunks (model_rate_stages,
!> documented at its interface in iem_model.f90; docs/architecture.md "RK4's stages as one
!> wavefront"). Each stage sweeps its bands in order as model_rate's evaluate_bands does,
!> but a stage takes a band only once the stage before has passed every node the band's cells
!> reach (iem_stage_wave's need), so the stages (2-4, or 1-4 when the step before left stage
!> 1 to this one) follow one another about a band apart and read the band's state, forces
!> and new state from the processor's caches. Every node's values take the same operations
!> in the same order as in evaluations one after the other, and the sums over nodes are
!> formed in the same order, so the results are bit for bit theirs. On a rank with halo
!> nodes each stage first evaluates its strip (iem_stage_wave's init_strips), whose nodes
!> include those the neighbours receive, and exchanges the next stage state from there.
submodule (iem_model) iem_model_stages
  use iem_timers, only: timer_switch, t_force, t_update, t_halo
  use iem_cell_bands, only: cell_bands_t
  use iem_stage_wave, only: wave_band_nodes
  implicit none

contains

  !> Documented at its interface in iem_model.f90.
  module procedure model_set_bands
    integer :: nw
    ! the wavefront's bands: as the model's where these are given, else sized for the caches
    nw = wave_band_nodes()
    if (present(band_nodes)) nw = band_nodes
    if (present(wave_nodes)) nw = wave_nodes
    if (this%split%active) then
      call this%bands%init(this%split%cells_in, lat%n_owned, this%split%d_node, band_nodes)
      call this%wave%free()
      if (this%bands%active) &
        call this%wave%init_strips(lat%cells, lat%n_owned, lat%n_local, nw, &
                                   size(this%ext_node), size(this%bc_node), size(this%load_tf))
    else
      call this%bands%init(lat%cells, lat%n_owned, band_nodes=band_nodes)
      call this%wave%init(lat%cells, this%bands, lat%n_owned, nw, size(this%ext_node), &
                          size(this%bc_node), size(this%load_tf))
    end if
  end procedure model_set_bands

  !> Documented at its interface in iem_model.f90: 4 values a node, no stiffness or capped
  !> damping, forces summed apart from the rates, and bands (on a rank with halo nodes, each
  !> stage's strip and bands).
  module procedure model_stages_fit
    fit = this%waves .and. n_state == 4 .and. this%bands%active .and. &
          this%beta == 0.0_wp .and. this%omega_cap == 0.0_wp .and. .not. this%sum_in_acc
    if (fit) then
      if (this%split%active) then
        fit = this%wave%strips
      else
        fit = lat%n_local == lat%n_owned
      end if
    end if
    if (fit) fit = this%wave%ready()
  end procedure model_stages_fit

  !> Documented at its interface in iem_model.f90.
  module procedure model_rate_stages
    real(wp) :: pd(wave_stages), sums(wave_stages)
    integer :: jb(wave_stages), js(wave_stages), done(wave_stages), nbs(wave_stages)
    integer :: ke(wave_stages), ne(wave_stages)
    logical :: stripped(wave_stages), strips
    real(wp) :: pd_none
    integer :: i, b, ld, n, s, q

    associate(wv => this%wave)
      ! on a rank with halo nodes each stage has its strip, evaluated first, and its bands
      strips = this%split%active
      if (strips .and. .not. present(halo)) error stop 'model_rate_stages: halo nodes need halo'
      do i = 1, wave_stages
        if (strips) then
          nbs(i) = wv%strip(i)%bands%n_bands()
        else
          nbs(i) = wv%bands%n_bands()
        end if
      end do
      ! each stage's loads at its time (as rebuilt there)
      do i = first, wave_stages
        do ld = 1, size(this%load_tf)
          wv%scale(ld, i) = tf_value(this%load_tf(ld), ts(i))
        end do
        wv%fx(:, :, i) = 0.0_wp
        do n = 1, size(this%load_node)
          s = this%load_slot(n)
          wv%fx(:, s, i) = wv%fx(:, s, i) + this%load_force(:, n)*wv%scale(this%load_id(n), i)
        end do
      end do
      call model_damping_arrays(this, lat)
      pd = 0.0_wp
      sums = 0.0_wp
      jb = 1
      js = 1
      done = 0
      ke = 0
      ne = 0
      stripped = .not. strips
      ! the first stage's halo values (received by its strip)
      if (strips) call exchange(.false., first)
      ! the wavefront: at every turn each stage takes its next band once the stage before has
      ! passed the nodes its cells reach; on a rank with halo nodes each stage first takes its
      ! strip (at the first turn, once the stage before has taken its own, which sent its
      ! halo values on), waiting for its halo values
      do while (any(done(first:) < nbs(first:)))
        do i = first, wave_stages
          if (.not. stripped(i)) then
            if (i > first) then
              if (.not. stripped(i - 1)) cycle
            end if
            call strip(i)
          end if
          if (done(i) == nbs(i)) cycle
          b = done(i) + 1
          if (i > first) then
            if (done(i - 1) < need(i, b)) cycle
          end if
          call band(i, b)
          done(i) = b
        end do
      end do
      if (strips) then
        ! the early nodes' mass damping powers after the bands' nodes (in node order); the
        ! halo nodes' forces the strips added, not used, cleared
        if (this%alpha > 0.0_wp) then
          do i = first, wave_stages
            call early_powers(i, huge(1))
          end do
        end if
        this%f(:, lat%n_owned + 1:lat%n_local) = 0.0_wp
      end if
      ! each stage's sums in model_rate's order; the terms of its work (add_work)
      p_ext = 0.0_wp
      p_damp = 0.0_wp
      do i = first, wave_stages
        p_ext(i) = 0.0_wp
        do s = 1, size(this%ext_node)
          p_ext(i) = p_ext(i) + wv%pe(s, i)
        end do
        do q = 1, size(this%bc_node)
          if (wv%on(q, i)) p_ext(i) = p_ext(i) + wv%pr(q, i)
        end do
        p_damp(i) = pd(i)
        call this%w_ext_acc%add_scaled(wv%pe(:, i), wdt(i))
        call this%w_ext_acc%add_scaled(wv%pr(:, i), wdt(i))
      end do
      total = sums(wave_stages)
      ! the model's terms and loads as the last stage left them; acc's imposed accelerations
      ! as each stage's evaluation wrote them
      this%pe_slot = wv%pe(:, wave_stages)
      this%pr_bc = wv%pr(:, wave_stages)
      this%pr_on = wv%on(:, wave_stages)
      this%fext = wv%fx(:, :, wave_stages)
      this%load_scale = wv%scale(:, wave_stages)
      do i = first, wave_stages
        call imposed(ts(i))
      end do
    end associate
  contains

    !> The band of the stage before (i - 1) after which stage i may sweep its band b.
    integer function need(i, b)
      integer, intent(in) :: i, b
      if (strips) then
        need = this%wave%strip(i)%need(b)
      else
        need = this%wave%need(b)
      end if
    end function need

    !> Stage i's strip on a rank with halo nodes: its halo values (waited for), the strip's
    !> cells (with the strips' kernel rows; the early nodes' forces summed there, the others'
    !> set aside), the pass over the nodes they complete, then the
    !> start of the exchange of the next stage state (whose values the neighbours need are
    !> among them).
    subroutine strip(i)
      integer, intent(in) :: i
      integer :: nc, r, j0
      logical :: timed_here
      associate(st => this%wave%strip(i), sp => this%wave%strip(i)%split)
        call exchange(.true., i)
        nc = sp%cells_bd%n_chunks()
        if (i == 1) then
          call this%cells(lat, sp%cells_bd, y0, this%f, .true., ts(i), this%wave%strip_rows%r, &
                          this%wave%strip_slots, pd_none, sp%at_bd, range=[1, nc], split=sp)
        else
          call this%cells(lat, sp%cells_bd, ys, this%f, .false., ts(i), &
                          this%wave%strip_rows%r, this%wave%strip_slots, pd_none, sp%at_bd, &
                          range=[1, nc], split=sp)
        end if
        call timer_switch(t_force, t_update, timed_here)
        ! the early nodes' runs (before the stage's bands: their dofs and loads searched
        ! from the first, and again for the bands)
        associate(nb => st%bands%n_bands())
          do r = st%bands%run_first(nb + 1), st%bands%run_first(nb + 2) - 1
            if (i == 1) then
              call run_terms(i, st%bands%runs(1, r), st%bands%runs(2, r), y0, j0, .true.)
            else
              call run_terms(i, st%bands%runs(1, r), st%bands%runs(2, r), ys, j0, .true.)
            end if
            call run_pass(i, st%bands%runs(1, r), st%bands%runs(2, r), j0)
          end do
        end associate
        jb(i) = 1
        js(i) = 1
        if (timed_here) call timer_switch(t_update, t_force)
        stripped(i) = .true.
        if (i < wave_stages) call exchange(.false., i + 1)
      end associate
    end subroutine strip

    !> The exchange of stage i's state (y0 for stage 1, else ys) started, or with finish
    !> finished, timed as halo exchange.
    subroutine exchange(finish, i)
      logical, intent(in) :: finish
      integer, intent(in) :: i
      logical :: timed_here
      call timer_switch(t_force, t_halo, timed_here)
      if (finish .and. i == 1) then
        call halo%finish(y0)
      else if (finish) then
        call halo%finish(ys)
      else if (i == 1) then
        call halo%start(y0)
      else
        call halo%start(ys)
      end if
      if (timed_here) call timer_switch(t_halo, t_force)
    end subroutine exchange

    !> Stage i's cells of band b (stage 1's at y0, the others' at ys), then its pass over the
    !> nodes the band completes (on a rank with halo nodes, with the strip's nodes the band
    !> completes).
    subroutine band(i, b)
      integer, intent(in) :: i, b
      logical :: timed
      if (strips) then
        associate(st => this%wave%strip(i))
          call cells(i, range_of(st%bands, b))
          call timer_switch(t_force, t_update, timed)
          call st%split%sum_side_of(this%f, st%edge(st%edge_first(b):st%edge_first(b + 1) - 1))
          call pass_runs(i, st%bands, b)
        end associate
      else
        call cells(i, range_of(this%wave%bands, b))
        call timer_switch(t_force, t_update, timed)
        call pass_runs(i, this%wave%bands, b)
      end if
      if (timed) call timer_switch(t_update, t_force)
    end subroutine band

    !> The chunks of band b of bands.
    pure function range_of(bands, b) result(range)
      type(cell_bands_t), intent(in) :: bands
      integer, intent(in) :: b
      integer :: range(2)
      range(1) = 1
      if (b > 1) range(1) = bands%last_chunk(b - 1) + 1
      range(2) = bands%last_chunk(b)
    end function range_of

    !> Stage i's terms and pass over the runs of band b of bands.
    subroutine pass_runs(i, bands, b)
      integer, intent(in) :: i, b
      type(cell_bands_t), intent(in) :: bands
      integer :: r, j0
      do r = bands%run_first(b), bands%run_first(b + 1) - 1
        ! (the terms read the stage state, which the pass then overwrites: two calls)
        if (i == 1) then
          call run_terms(i, bands%runs(1, r), bands%runs(2, r), y0, j0, .false.)
        else
          call run_terms(i, bands%runs(1, r), bands%runs(2, r), ys, j0, .false.)
        end if
        call run_pass(i, bands%runs(1, r), bands%runs(2, r), j0)
      end do
    end subroutine pass_runs

    !> Stage i's cell forces of the chunks range(1)..range(2) of its table (its kernel rows
    !> and slots; on a rank with halo nodes, of its strip's interior chunks) at its state;
    !> stage 1 commits (the springs' history, the damage) at its time.
    subroutine cells(i, range)
      integer, intent(in) :: i, range(2)
      if (strips) then
        associate(sp => this%wave%strip(i)%split)
          if (i == 1) then
            call this%cells(lat, sp%cells_in, y0, this%f, .true., ts(i), this%wave%rows(i)%r, &
                            this%wave%slots(i), pd_none, sp%at_in, range=range, split=sp)
          else
            call this%cells(lat, sp%cells_in, ys, this%f, .false., ts(i), &
                            this%wave%rows(i)%r, this%wave%slots(i), pd_none, sp%at_in, &
                            range=range, split=sp)
          end if
        end associate
      else if (i == 1) then
        call this%cells(lat, lat%cells, y0, this%f, .true., ts(i), this%wave%rows(i)%r, &
                        this%wave%slots(i), pd_none, range=range)
      else
        call this%cells(lat, lat%cells, ys, this%f, .false., ts(i), this%wave%rows(i)%r, &
                        this%wave%slots(i), pd_none, range=range)
      end if
    end subroutine cells

    !> Stage i's early nodes' mass damping powers added to its sum, those before node lo.
    subroutine early_powers(i, lo)
      integer, intent(in) :: i, lo
      associate(sp => this%wave%strip(i)%split, pw => this%wave%strip(i)%pw)
        do while (ke(i) < size(sp%early))
          if (sp%d_node(sp%early(ke(i) + 1)) >= lo) exit
          ke(i) = ke(i) + 1
          pd(i) = pd(i) + pw(ke(i))
        end do
      end associate
    end subroutine early_powers

    !> Stage i's terms of the nodes lo..hi at its state y (y0 or ys), whose forces are
    !> complete, as model_rate's run_nodes forms them: reactions (from j0, the run's first
    !> prescribed dof in bc_by_node), loads, mass damping powers (early: a strip's early
    !> nodes, whose powers are kept for the sum in node order).
    subroutine run_terms(i, lo, hi, y, j0, early)
      integer, intent(in) :: i, lo, hi
      real(wp), intent(in), contiguous :: y(:, :)
      integer, intent(out) :: j0
      logical, intent(in) :: early
      integer :: l
      real(wp) :: apart
      associate(wv => this%wave, f => this%f)
        do while (jb(i) <= size(this%bc_by_node))
          if (this%bc_node(this%bc_by_node(jb(i))) >= lo) exit
          jb(i) = jb(i) + 1
        end do
        j0 = jb(i)
        do while (jb(i) <= size(this%bc_by_node))
          if (this%bc_node(this%bc_by_node(jb(i))) > hi) exit
          associate(q => this%bc_by_node(jb(i)))
            ! stage 1 commits: its reactions are kept
            call this%reaction_terms(q, f, y, ts(i), wv%fx(:, :, i), i == 1, wv%pr(q, i), &
                                     wv%on(q, i))
          end associate
          jb(i) = jb(i) + 1
        end do
        do while (js(i) <= size(this%ext_node))
          if (this%ext_node(js(i)) >= lo) exit
          js(i) = js(i) + 1
        end do
        do while (js(i) <= size(this%ext_node))
          if (this%ext_node(js(i)) > hi) exit
          l = this%ext_node(js(i))
          wv%pe(js(i), i) = wv%fx(1, js(i), i)*y(3, l) + wv%fx(2, js(i), i)*y(4, l)
          f(:, l) = f(:, l) - wv%fx(:, js(i), i)
          js(i) = js(i) + 1
        end do
        if (this%alpha > 0.0_wp .and. early) then
          apart = 0.0_wp
          call mass_damping_powers(hi - lo + 1, this%alpha, this%mass(lo:hi), y(:, lo:hi), &
                                   this%pw_node(lo:hi), apart, this%wd_node(lo:hi), wdt(i))
          this%wave%strip(i)%pw(ne(i) + 1:ne(i) + hi - lo + 1) = this%pw_node(lo:hi)
          ne(i) = ne(i) + hi - lo + 1
        else if (this%alpha > 0.0_wp) then
          if (strips) call early_powers(i, lo)
          call mass_damping_powers(hi - lo + 1, this%alpha, this%mass(lo:hi), y(:, lo:hi), &
                                   this%pw_node(lo:hi), pd(i), this%wd_node(lo:hi), wdt(i))
        end if
      end associate
    end subroutine run_terms

    !> Stage i's update of the nodes lo..hi (model_rate's run_nodes' pass), then the
    !> prescribed velocities of the next stage state it made (its dofs from j0 on).
    subroutine run_pass(i, lo, hi, j0)
      integer, intent(in) :: i, lo, hi, j0
      integer :: j
      real(wp) :: part
      associate(f => this%f)
        if (i == 1) then
          call rk4_first_pass(hi - lo + 1, this%alpha, this%mass(lo:hi), wdt(i), h(i), &
                              y0(:, lo:hi), f(:, lo:hi), ynew(:, lo:hi), ys(:, lo:hi))
        else if (i < wave_stages) then
          call rk4_mid_pass(hi - lo + 1, this%alpha, this%mass(lo:hi), wdt(i), h(i), &
                            y0(:, lo:hi), f(:, lo:hi), ynew(:, lo:hi), ys(:, lo:hi))
        end if
        if (i < wave_stages) then
          ! the next stage state's prescribed velocities (model_prescribe at its time)
          do j = j0, jb(i) - 1
            call prescribe_dof(this%bc_by_node(j), ts(i + 1))
          end do
        else
          call rk4_last_pass(hi - lo + 1, this%alpha, this%mass(lo:hi), wdt(i), ys(:, lo:hi), &
                             f(:, lo:hi), ynew(:, lo:hi), part)
          sums(i) = sums(i) + part
        end if
      end associate
    end subroutine run_pass

    !> model_prescribe for prescribed dof q of ys at time tq.
    subroutine prescribe_dof(q, tq)
      integer, intent(in) :: q
      real(wp), intent(in) :: tq
      integer :: bq
      bq = this%bc_id(q)
      if (tq >= this%bc_release(bq)) return
      ys(2 + this%bc_comp(q), this%bc_node(q)) = this%bc_velocity(this%bc_comp(q), bq)* &
                                                 tf_value(this%bc_tf(bq), tq)
    end subroutine prescribe_dof

    !> model_rate's imposed accelerations of the prescribed dofs at time tq (into acc).
    subroutine imposed(tq)
      real(wp), intent(in) :: tq
      integer :: q, bq, cq
      if (size(acc, 2) == 0) return
      do q = 1, size(this%bc_node)
        bq = this%bc_id(q)
        if (tq >= this%bc_release(bq)) cycle
        cq = this%bc_comp(q)
        acc(cq, this%bc_node(q)) = this%bc_velocity(cq, bq)*tf_rate(this%bc_tf(bq), tq)
      end do
    end subroutine imposed
  end procedure model_rate_stages
end submodule iem_model_stages
