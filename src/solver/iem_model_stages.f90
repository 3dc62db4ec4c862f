!> RK4's stages as one wavefront over the bands of a rank's chunks (model_rate_stages,
!> documented at its interface in iem_model.f90; docs/architecture.md "RK4's stages as one
!> wavefront"). Each stage sweeps its bands in order as model_rate's evaluate_bands does,
!> but a stage takes a band only once the stage before has passed every node the band's cells
!> reach (iem_stage_wave's need), so the stages (2-4, or 1-4 when the step before left stage
!> 1 to this one) follow one another about a band apart and read the band's state, forces
!> and new state from the processor's caches. Every node's values take the same operations
!> in the same order as in evaluations one after the other, and the sums over nodes are
!> formed in the same order, so the results are bit for bit theirs.
submodule (iem_model) iem_model_stages
  use iem_timers, only: timer_switch, t_force, t_update
  implicit none

contains

  !> Documented at its interface in iem_model.f90.
  module procedure model_set_bands
    if (this%split%active) then
      call this%bands%init(this%split%cells_in, lat%n_owned, this%split%d_node, band_nodes)
      call this%wave%free()
    else
      call this%bands%init(lat%cells, lat%n_owned, band_nodes=band_nodes)
      call this%wave%init(lat%cells, this%bands, size(this%ext_node), size(this%bc_node), &
                          size(this%load_tf))
    end if
  end procedure model_set_bands

  !> Documented at its interface in iem_model.f90: 4 values a node, no stiffness or capped
  !> damping, forces summed apart from the rates, and bands on a rank without halo nodes.
  module procedure model_stages_fit
    fit = this%waves .and. n_state == 4 .and. this%bands%active .and. &
          this%beta == 0.0_wp .and. this%omega_cap == 0.0_wp .and. .not. this%sum_in_acc .and. &
          .not. this%split%active .and. lat%n_local == lat%n_owned
    if (fit) fit = this%wave%ready()
  end procedure model_stages_fit

  !> Documented at its interface in iem_model.f90.
  module procedure model_rate_stages
    real(wp) :: pd(wave_stages), sums(wave_stages)
    integer :: jb(wave_stages), js(wave_stages), done(wave_stages)
    integer :: i, b, nb, ld, n, s, q

    associate(wv => this%wave)
      nb = this%bands%n_bands()
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
      ! the wavefront: the first stage takes the next band at every turn, each later one the
      ! next band once the stage before has passed the nodes its cells reach
      do while (done(wave_stages) < nb)
        do i = first, wave_stages
          if (done(i) == nb) cycle
          b = done(i) + 1
          if (i > first) then
            if (done(i - 1) < wv%need(b)) cycle
          end if
          call band(i, b)
          done(i) = b
        end do
      end do
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

    !> Stage i's cells of band b (stage 1's at y0, the others' at ys), then its pass over the
    !> nodes the band completes.
    subroutine band(i, b)
      integer, intent(in) :: i, b
      integer :: c1, r, j0
      logical :: timed
      c1 = 1
      if (b > 1) c1 = this%bands%last_chunk(b - 1) + 1
      if (i == 1) then
        call cells(i, [c1, this%bands%last_chunk(b)], y0)
      else
        call cells(i, [c1, this%bands%last_chunk(b)], ys)
      end if
      call timer_switch(t_force, t_update, timed)
      do r = this%bands%run_first(b), this%bands%run_first(b + 1) - 1
        ! (the terms read the stage state, which the pass then overwrites: two calls)
        if (i == 1) then
          call run_terms(i, this%bands%runs(1, r), this%bands%runs(2, r), y0, j0)
        else
          call run_terms(i, this%bands%runs(1, r), this%bands%runs(2, r), ys, j0)
        end if
        call run_pass(i, this%bands%runs(1, r), this%bands%runs(2, r), j0)
      end do
      if (timed) call timer_switch(t_update, t_force)
    end subroutine band

    !> Stage i's cell forces of the chunks range(1)..range(2) at the state y (its kernel rows
    !> and slots); stage 1 commits (the springs' history, the damage) at its time.
    subroutine cells(i, range, y)
      integer, intent(in) :: i, range(2)
      real(wp), intent(in), contiguous :: y(:, :)
      real(wp) :: pd_cells
      call this%cells(lat, lat%cells, y, this%f, i == 1, ts(i), this%wave%rows(i)%r, &
                      this%wave%slots(i), pd_cells, range=range)
    end subroutine cells

    !> Stage i's terms of the nodes lo..hi at its state y (y0 or ys), whose forces are
    !> complete, as model_rate's run_nodes forms them: reactions (from j0, the run's first
    !> prescribed dof in bc_by_node), loads, mass damping powers.
    subroutine run_terms(i, lo, hi, y, j0)
      integer, intent(in) :: i, lo, hi
      real(wp), intent(in), contiguous :: y(:, :)
      integer, intent(out) :: j0
      integer :: l
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
        if (this%alpha > 0.0_wp) then
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
